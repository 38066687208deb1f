//! Pictures: known scenes give the expected pixels on every render path, the GPU paths agree with
//! the cpu path, a simulation frame is not blank, and `mochi render` / `simulate --render-every`
//! write PNG frames (and fail cleanly on bad input). The GPU paths run on any adapter (lavapipe
//! in CI); under `CI=true` a missing adapter fails.

mod common;

use common::cli::mochi;
use mochi::gpu::Need;
use mochi::render::{
    Camera, ColorBy, Image, Picture, RenderChoice, Renderer, Scene, read_png, viridis,
};
use mochi::scenes::{Layout, Scene as Dataset, SceneSpec, generate};
use std::path::Path;

/// Every path that can be tested here: cpu always, the GPU paths where an adapter has them
/// (a missing one fails under CI).
fn renderers() -> Vec<Renderer> {
    let mut all = vec![Renderer::open(RenderChoice::Cpu).unwrap().0];
    for (choice, need) in [
        (RenderChoice::WgpuCompute, Need::Compute),
        (RenderChoice::WgpuRq, Need::RayQuery),
    ] {
        if common::adapter_for(need, choice.name()) {
            all.push(Renderer::open(choice).expect("a probed adapter opens").0);
        }
    }
    all
}

/// Looking along +y at the origin from y = -5.
fn axis_camera() -> Camera {
    Camera {
        eye: [0.0, -5.0, 0.0],
        look_at: [0.0; 3],
        fov_deg: 30.0,
    }
}

fn rgb(image: &Image, x: u32, y: u32) -> [f32; 3] {
    image.rgb(x, y).map(|c| c as f32 / 255.0)
}

/// Whether `c` is a shade of `base` (the same colour, lighter or darker): each channel's share
/// of the sum within 0.06.
fn shade_of(c: [f32; 3], base: [f32; 3]) -> bool {
    let (sc, sb) = (c.iter().sum::<f32>(), base.iter().sum::<f32>());
    (0..3).all(|k| (c[k] / sc - base[k] / sb).abs() < 0.06)
}

/// A light grey: the background.
fn is_background(c: [f32; 3]) -> bool {
    c.iter().all(|&x| x > 0.7) && (c[0] - c[2]).abs() < 0.08
}

#[test]
fn a_single_sphere_fills_the_centre_with_its_colour() {
    let scene = Scene::new(&[[0.0; 3]], &[0.6], &[1.0], (0.0, 1.0)).unwrap();
    let picture = Picture::new(40, 30, axis_camera());
    for mut renderer in renderers() {
        let image = renderer.render(&scene, &picture).unwrap();
        let name = renderer.name();
        for (x, y) in [(19, 14), (20, 15), (19, 15), (20, 14)] {
            let c = rgb(&image, x, y);
            assert!(shade_of(c, viridis(1.0)), "{name}: centre {c:?}");
        }
        for (x, y) in [(0, 0), (39, 0), (0, 29), (39, 29)] {
            let c = rgb(&image, x, y);
            assert!(is_background(c), "{name}: corner {c:?}");
        }
    }
}

#[test]
fn the_nearer_of_two_spheres_on_the_view_axis_wins() {
    // Yellow (value 1) in front, a larger purple one (value 0) behind it.
    let positions = [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]];
    let scene = Scene::new(&positions, &[1.0, 0.3], &[0.0, 1.0], (0.0, 1.0)).unwrap();
    let picture = Picture::new(40, 30, axis_camera());
    for mut renderer in renderers() {
        let image = renderer.render(&scene, &picture).unwrap();
        let name = renderer.name();
        let centre = rgb(&image, 20, 15);
        assert!(shade_of(centre, viridis(1.0)), "{name}: centre {centre:?}");
        // Beside the small front sphere, still on the big one behind it.
        let side = rgb(&image, 20, 7);
        assert!(
            shade_of(side, viridis(0.0)),
            "{name}: above the centre {side:?}"
        );
    }
}

#[test]
fn a_wall_in_front_tints_what_is_behind_it_and_hides_nothing() {
    // A square wall (two triangles) at y = -2 covering the picture's left half, between the
    // eye and a sphere at the origin.
    let sphere = Scene::new(&[[0.0; 3]], &[0.6], &[1.0], (0.0, 1.0)).unwrap();
    let square = [
        [[-3.0, -2.0, -3.0], [0.0, -2.0, -3.0], [0.0, -2.0, 3.0]],
        [[-3.0, -2.0, -3.0], [0.0, -2.0, 3.0], [-3.0, -2.0, 3.0]],
    ];
    let walled = sphere.clone().with_walls(&square).unwrap();
    let picture = Picture::new(40, 30, axis_camera());
    for mut renderer in renderers() {
        let name = renderer.name();
        let bare = renderer.render(&sphere, &picture).unwrap();
        let seen = renderer.render(&walled, &picture).unwrap();
        let changed = |x, y| bare.rgb(x, y) != seen.rgb(x, y);
        // Left of the centre: the sphere and the background, both tinted, the sphere still
        // its own colour.
        assert!(
            changed(17, 15) && changed(2, 15),
            "{name}: the wall is not drawn"
        );
        let c = rgb(&seen, 17, 15);
        assert!(
            shade_of(c, viridis(1.0)) || c[1] > c[2],
            "{name}: sphere hidden: {c:?}"
        );
        // Right of the wall's edge: untouched.
        for (x, y) in [(22, 15), (37, 2), (37, 27)] {
            assert!(
                !changed(x, y),
                "{name}: ({x}, {y}) changed with no wall there"
            );
        }
    }
    assert!(
        Scene::new(&[], &[], &[], (0.0, 1.0))
            .unwrap()
            .with_walls(&[[[0.0, f32::NAN, 0.0], [1.0; 3], [0.0; 3]]])
            .is_err()
    );
}

#[test]
fn gpu_paths_draw_the_cpu_picture() {
    let spheres = generate(&SceneSpec {
        scene: Dataset::Poly12,
        n: 300,
        seed: 5,
        layout: Layout::Random,
    })
    .unwrap();
    let radii: Vec<f32> = spheres.radii().iter().map(|r| r * 60.0).collect();
    let values = ColorBy::Radius.values(&mochi::render::SphereValues {
        positions: spheres.centers(),
        radii: &radii,
        ..Default::default()
    });
    let range = mochi::render::value_range(&values);
    let scene = Scene::new(spheres.centers(), &radii, &values, range).unwrap();
    let (lo, hi) = scene.bounds().unwrap();
    // A tube of 48 wall triangles about the spheres' vertical axis, half as wide as they spread.
    let (c, w) = ([0, 1].map(|a| (lo[a] + hi[a]) / 2.0), (hi[0] - lo[0]) / 4.0);
    let at = |k: usize, z: f64| {
        let phi = k as f64 * std::f64::consts::TAU / 24.0;
        [c[0] + w * phi.cos(), c[1] + w * phi.sin(), z].map(|x| x as f32)
    };
    let tube: Vec<[[f32; 3]; 3]> = (0..24)
        .flat_map(|k| {
            let (a, b) = (
                [at(k, lo[2]), at(k, hi[2])],
                [at(k + 1, lo[2]), at(k + 1, hi[2])],
            );
            [[a[0], b[0], b[1]], [a[0], b[1], a[1]]]
        })
        .collect();
    let scene = scene.with_walls(&tube).unwrap();
    assert_eq!(scene.wall_triangles(), 48);
    let picture = Picture {
        samples: 2,
        shadows: true,
        floor: Some((
            [lo[0] - 1.0, lo[1] - 1.0, lo[2]],
            [hi[0] + 1.0, hi[1] + 1.0, hi[2]],
        )),
        ..Picture::new(64, 48, Camera::framing(lo, hi, 64.0 / 48.0, 40.0))
    };
    let mut all = renderers().into_iter();
    let want = all.next().unwrap().render(&scene, &picture).unwrap();
    let background = want.pixels.iter().filter(|&&p| p == want.pixels[0]).count();
    assert!(
        background < want.pixels.len() / 2,
        "the spheres fill the picture"
    );
    for mut renderer in all {
        let got = renderer.render(&scene, &picture).unwrap();
        let close = (0..48)
            .flat_map(|y| (0..64).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let (a, b) = (want.rgb(x, y), got.rgb(x, y));
                (0..3).all(|k| a[k].abs_diff(b[k]) <= 3)
            })
            .count();
        assert!(
            close * 100 >= 99 * 64 * 48,
            "{}: only {close} of {} pixels match the cpu path",
            renderer.name(),
            64 * 48
        );
    }
}

#[test]
fn a_sphere_casts_its_shadow_on_the_floor() {
    // Looking straight down on a sphere above a floor: with shadow rays a patch of floor gets
    // darker, and nothing gets lighter.
    let scene = Scene::new(&[[0.0, 0.0, 0.5]], &[0.4], &[0.5], (0.0, 1.0)).unwrap();
    let camera = Camera {
        eye: [0.0, 0.0, 6.0],
        look_at: [0.0; 3],
        fov_deg: 50.0,
    };
    let picture = |shadows| Picture {
        shadows,
        floor: Some(([-4.0, -4.0, 0.0], [4.0, 4.0, 0.0])),
        ..Picture::new(48, 48, camera)
    };
    for mut renderer in renderers() {
        let plain = renderer.render(&scene, &picture(false)).unwrap();
        let shadowed = renderer.render(&scene, &picture(true)).unwrap();
        let mut darker = 0;
        for y in 0..48 {
            for x in 0..48 {
                let (a, b) = (rgb(&plain, x, y), rgb(&shadowed, x, y));
                let change = b.iter().sum::<f32>() - a.iter().sum::<f32>();
                assert!(
                    change <= 0.01,
                    "{}: ({x}, {y}) got lighter",
                    renderer.name()
                );
                darker += usize::from(change < -0.3);
            }
        }
        assert!(
            darker > 20,
            "{}: {darker} pixels in shadow",
            renderer.name()
        );
    }
}

#[test]
fn an_empty_scene_is_background_and_bad_pictures_are_errors() {
    let scene = Scene::new(&[], &[], &[], (0.0, 1.0)).unwrap();
    for mut renderer in renderers() {
        let image = renderer
            .render(&scene, &Picture::new(8, 6, axis_camera()))
            .unwrap();
        assert!(
            image
                .pixels
                .chunks(8)
                .all(|row| row.iter().all(|&p| p == row[0]))
        );
        assert!(is_background(rgb(&image, 0, 0)));
        for bad in [
            Picture::new(0, 6, axis_camera()),
            Picture {
                samples: 9,
                ..Picture::new(8, 6, axis_camera())
            },
            Picture::new(
                8,
                6,
                Camera {
                    fov_deg: 0.0,
                    ..axis_camera()
                },
            ),
            Picture::new(
                8,
                6,
                Camera {
                    look_at: [0.0, -5.0, 0.0],
                    ..axis_camera()
                },
            ),
        ] {
            assert!(renderer.render(&scene, &bad).is_err(), "{bad:?}");
        }
    }
    assert!(Scene::new(&[[0.0; 3]], &[-1.0], &[0.0], (0.0, 1.0)).is_err());
    assert!(Scene::new(&[[f32::NAN; 3]], &[1.0], &[0.0], (0.0, 1.0)).is_err());
    assert!(Scene::new(&[[0.0; 3]], &[1.0, 2.0], &[0.0], (0.0, 1.0)).is_err());
}

// ----------------------------------------------------------------------------------------------
// The command line
// ----------------------------------------------------------------------------------------------

/// Share of pixels that are not the background's light grey.
fn not_background(image: &Image) -> f64 {
    let n = (0..image.height)
        .flat_map(|y| (0..image.width).map(move |x| (x, y)))
        .filter(|&(x, y)| !is_background(rgb(image, x, y)))
        .count();
    n as f64 / image.pixels.len() as f64
}

#[test]
fn render_draws_a_runs_mesh_walls_where_they_are_at_its_frame() {
    // A small drum whose 12-sided tube turns about half a side in 400 steps.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = mochi(
        &[
            "simulate",
            "--scene",
            "drum",
            "-n",
            "60",
            "--steps",
            "400",
            "--frame-every",
            "400",
            "--set",
            "drum_sides=12",
            "--set",
            "drum_omega=50",
            "--backend",
            "cpu",
            "-q",
            "-o",
            "turning",
        ],
        d,
    );
    assert_eq!(run.0, Some(0), "{run:?}");
    // The same run said to stand still: the same frame, its tube at rest.
    std::fs::create_dir(d.join("still")).unwrap();
    std::fs::copy(
        d.join("turning/frame_00000400.vtu"),
        d.join("still/last.vtu"),
    )
    .unwrap();
    let scene = std::fs::read_to_string(d.join("turning/scene.toml")).unwrap();
    let still: String = scene
        .lines()
        .map(|l| match l.starts_with("omega = ") {
            true => "omega = 0.0\n".to_owned(),
            false => format!("{l}\n"),
        })
        .collect();
    assert_ne!(still, scene);
    std::fs::write(d.join("still/scene.toml"), still).unwrap();
    let draw = |frame: &str, png: &str, walls: &str| {
        let args = [
            "render",
            frame,
            "-o",
            png,
            "--size",
            "80x60",
            "--renderer",
            "cpu",
        ];
        let run = mochi(&args, d);
        assert_eq!(run.0, Some(0), "{run:?}");
        assert!(run.1.contains(walls), "{run:?}");
        read_png(&d.join(png)).unwrap()
    };
    let drawn = "with 24 wall triangles drawn";
    let turned = draw("turning/frame_00000400.vtu", "a.png", drawn);
    let at_rest = draw("still/last.vtu", "b.png", drawn);
    assert_ne!(turned.pixels, at_rest.pixels, "the tube is drawn at rest");
    // Without the run's scene beside it, the frame is drawn without walls.
    std::fs::copy(d.join("still/last.vtu"), d.join("alone.vtu")).unwrap();
    let alone = draw("alone.vtu", "c.png", "60 spheres drawn");
    assert_ne!(alone.pixels, at_rest.pixels);
}

#[test]
fn simulate_renders_frames_that_are_not_blank_and_render_redraws_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = mochi(
        &[
            "simulate",
            "--scene",
            "slab",
            "-n",
            "400",
            "--steps",
            "20",
            "--frame-every",
            "10",
            "--render-every",
            "10",
            "--size",
            "96x72",
            "--samples",
            "1",
            "--fit",
            "spheres",
            "--renderer",
            "cpu",
            "--gif",
            "run.gif",
            "-q",
            "-o",
            "out",
        ],
        d,
    );
    assert_eq!(run.0, Some(0), "{run:?}");
    for step in [0, 10, 20] {
        let png = d.join(format!("out/frame_{step:08}.png"));
        let image = read_png(&png).unwrap();
        assert_eq!((image.width, image.height), (96, 72));
        let share = not_background(&image);
        assert!(
            share > 0.1,
            "{}: {share} of the pixels drawn",
            png.display()
        );
    }
    assert!(d.join("run.gif").metadata().unwrap().len() > 100);

    // One frame, then the whole folder with the speed colours.
    let run = mochi(
        &[
            "render",
            "out/frame_00000020.vtu",
            "-o",
            "one.png",
            "--size",
            "80x60",
            "--renderer",
            "cpu",
        ],
        d,
    );
    assert_eq!(run.0, Some(0), "{run:?}");
    assert_eq!(read_png(&d.join("one.png")).unwrap().width, 80);
    let run = mochi(
        &[
            "render",
            "out",
            "-o",
            "pictures",
            "--size",
            "64x48",
            "--color-by",
            "speed",
            "--samples",
            "1",
            "--no-shadows",
            "--eye",
            "0.5,-2,1",
            "--look-at",
            "0.5,0.5,0.1",
            "--gif",
            "pictures/run.gif",
        ],
        d,
    );
    assert_eq!(run.0, Some(0), "{run:?}");
    assert!(run.2.contains("render: auto picked"), "{}", run.2);
    for step in [0, 10, 20] {
        assert!(d.join(format!("pictures/frame_{step:08}.png")).is_file());
    }
    let gif = std::fs::read(d.join("pictures/run.gif")).unwrap();
    assert!(gif.starts_with(b"GIF89a"));
}

#[test]
fn render_fails_cleanly_on_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("bad.vtu"), b"<VTKFile>not a frame").unwrap();
    std::fs::write(d.join("spheres.csv"), "x,y,z,r\n0,0,0,1\n").unwrap();
    std::fs::create_dir(d.join("empty")).unwrap();
    for args in [
        &["render", "missing.vtu"][..],
        &["render", "bad.vtu"],
        &["render", "empty"],
        &["render", "spheres.csv", "--size", "0x10"],
        &["render", "spheres.csv", "--size", "ten"],
        &["render", "spheres.csv", "--eye", "1,2"],
        &["render", "spheres.csv", "--range", "2,1"],
        &["render", "spheres.csv", "--samples", "7"],
    ] {
        let (code, _, stderr) = mochi(args, d);
        assert_eq!(code, Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.starts_with("error:") && !stderr.contains("panicked"),
            "{args:?}: {stderr}"
        );
    }
    assert!(!d.join("spheres.png").exists() && !d.join("bad.png").exists());
    let (code, out, err) = mochi(
        &[
            "render",
            "spheres.csv",
            "--size",
            "32x24",
            "--renderer",
            "cpu",
        ],
        d,
    );
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(d.join("spheres.png").is_file());
}

#[test]
fn coincident_spheres_draw_as_their_largest() {
    // 5,000 spheres at the origin of radii up to 0.6: every path draws the one of radius 0.6.
    let n = 5000;
    let radii: Vec<f32> = (0..n).map(|k| 0.6 - (k % 10) as f32 * 0.05).collect();
    let coincident = Scene::new(&vec![[0.0; 3]; n], &radii, &vec![1.0; n], (0.0, 1.0)).unwrap();
    let single = Scene::new(&[[0.0; 3]], &[0.6], &[1.0], (0.0, 1.0)).unwrap();
    assert_eq!(coincident.len(), 1);
    let picture = Picture::new(40, 30, axis_camera());
    for mut renderer in renderers() {
        let want = renderer.render(&single, &picture).unwrap();
        let got = renderer.render(&coincident, &picture).unwrap();
        assert!(got.pixels == want.pixels, "{}", renderer.name());
    }
}

/// Share of the pixels of `image` in the colours of the spheres (viridis greens and blues, far
/// from the grey floor, the white-blue background and the legend's panel).
fn sphere_share(image: &Image) -> f64 {
    let mut n = 0;
    for y in 0..image.height {
        for x in 0..image.width {
            let [r, g, b] = rgb(image, x, y);
            let grey = (r - g).abs() < 0.08 && (g - b).abs() < 0.08;
            if !grey && !is_background([r, g, b]) {
                n += 1;
            }
        }
    }
    n as f64 / (image.width * image.height) as f64
}

#[test]
fn the_default_framing_closes_in_on_a_heap_in_a_large_box_but_not_on_strays() {
    // A heap of 400 spheres on the floor of a 1 m box, and two spheres rolled off to corners.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("scene.toml"),
        "box_lo = [0.0, 0.0, 0.0]\nbox_hi = [1.0, 1.0, 1.0]\n",
    )
    .unwrap();
    let mut rows = String::from("x,y,z,r\n");
    for k in 0..400 {
        let (i, j, l) = (k % 10, (k / 10) % 10, k / 100);
        let at = [
            0.45 + 0.01 * i as f32,
            0.45 + 0.01 * j as f32,
            0.005 + 0.01 * l as f32,
        ];
        rows += &format!("{},{},{},0.005\n", at[0], at[1], at[2]);
    }
    rows += "0.02,0.02,0.005,0.005\n0.98,0.97,0.005,0.005\n";
    std::fs::write(d.join("frame_00000007.csv"), rows).unwrap();
    let share = |fit: &str| {
        let image = small_picture(
            d,
            "frame_00000007.csv",
            &format!("{fit}.png"),
            &["--fit", fit],
        );
        sphere_share(&image)
    };
    let (auto, whole_box, spheres) = (share("auto"), share("box"), share("spheres"));
    // The box's framing shows the heap small; the spheres' framing, stretched to the strays,
    // little larger; auto frames the heap itself.
    assert!(auto > 4.0 * whole_box, "auto {auto}, box {whole_box}");
    assert!(auto > 2.0 * spheres, "auto {auto}, spheres {spheres}");
}

#[test]
fn render_colours_by_material() {
    // Two spheres of the same size side by side, of materials 0 and 1: by material they take
    // viridis's two ends (purple, yellow); by radius, both its middle (teal), neither end.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("two.csv"),
        "x,y,z,r,vx,vy,vz,wx,wy,wz,material\n\
         -1,0,0,0.9,0,0,0,0,0,0,0\n\
         1,0,0,0.9,0,0,0,0,0,0,1\n",
    )
    .unwrap();
    let hues = |color_by: &str| {
        let png = format!("{color_by}.png");
        let image = small_picture(d, "two.csv", &png, &["--color-by", color_by]);
        let rgb = |p: u32| [p & 0xff, (p >> 8) & 0xff, (p >> 16) & 0xff].map(|c| c as f32);
        let purple = image.pixels.iter().map(|&p| rgb(p));
        let purple = purple
            .filter(|[r, g, b]| b > &(1.3 * g) && r > &(1.3 * g))
            .count();
        let yellow = image.pixels.iter().map(|&p| rgb(p));
        let yellow = yellow
            .filter(|[r, g, b]| r > &(1.5 * b) && g > &(1.5 * b))
            .count();
        (purple, yellow)
    };
    let (purple, yellow) = hues("material");
    assert!(
        purple > 100 && yellow > 100,
        "by material: {purple} purple, {yellow} yellow pixels"
    );
    let (purple, yellow) = hues("radius");
    assert!(
        purple < 10 && yellow < 10,
        "by radius: {purple} purple, {yellow} yellow pixels"
    );
}

#[test]
fn auto_colours_a_heap_at_rest_by_height_and_a_collapse_by_speed() {
    // A pyramid of 30 spheres of radius 5 mm, at rest, then the same falling apart.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mut rest, mut falling) = (String::from("x,y,z,r,vx,vy,vz\n"), String::new());
    falling += "x,y,z,r,vx,vy,vz\n";
    for (layer, side) in [(0, 4), (1, 3), (2, 2), (3, 1)] {
        for k in 0..side * side {
            let (i, j) = (k % side, k / side);
            let at = |a: i32| 0.01 * a as f32 + 0.005 * layer as f32;
            let (x, y, z) = (at(i), at(j), 0.005 + 0.008 * layer as f32);
            rest += &format!("{x},{y},{z},0.005,0,0,0\n");
            falling += &format!("{x},{y},{z},0.005,{},0,-0.3\n", 0.1 * i as f32);
        }
    }
    std::fs::write(d.join("rest.csv"), rest).unwrap();
    std::fs::write(d.join("falling.csv"), falling).unwrap();
    let draw = |frame: &str, color_by: &str| {
        let png = format!("{frame}-{color_by}.png");
        small_picture(d, &format!("{frame}.csv"), &png, &["--color-by", color_by]).pixels
    };
    let auto = draw("rest", "auto");
    assert!(auto == draw("rest", "height"), "a heap at rest: by height");
    assert!(auto != draw("rest", "radius") && auto != draw("rest", "speed"));
    let auto = draw("falling", "auto");
    assert!(auto == draw("falling", "speed"), "a collapse: by speed");
    assert!(auto != draw("falling", "height"));
}

#[test]
fn the_legend_writes_its_label_into_the_picture() {
    // Two spheres whose radius and height are both 0.5: coloured alike by either in the range
    // 0..1, so the pictures differ only where the legend's labels differ.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("two.csv"), "x,y,z,r\n-1,0,0.5,0.5\n1,0,0.5,0.5\n").unwrap();
    let (w, h) = (240, 180);
    let draw = |color_by: &str, legend: bool| {
        let png = format!("{color_by}-{legend}.png");
        let mut args = vec![
            "render",
            "two.csv",
            "-o",
            &png,
            "--size",
            "240x180",
            "--samples",
            "1",
            "--range",
            "0,1",
            "--renderer",
            "cpu",
            "--color-by",
            color_by,
        ];
        if !legend {
            args.push("--no-legend");
        }
        let run = mochi(&args, d);
        assert_eq!(run.0, Some(0), "{run:?}");
        read_png(&d.join(&png)).unwrap()
    };
    let (radius, height) = (draw("radius", true), draw("height", true));
    let bare = draw("radius", false);
    // The two labels differ above the colour bar (which starts a quarter down) at the right;
    // elsewhere at most the veil's left edge moves with the wider label.
    let differ: Vec<(u32, u32)> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .filter(|&(x, y)| radius.rgb(x, y) != height.rgb(x, y))
        .collect();
    let in_label = differ.iter().filter(|&&(_, y)| y < h / 4).count();
    assert!(in_label > 50, "{in_label} pixels of the label differ");
    assert!(differ.iter().all(|&(x, _)| x > w / 2), "{differ:?}");
    let columns_below: std::collections::BTreeSet<u32> = differ
        .iter()
        .filter(|&&(_, y)| y >= h / 4)
        .map(|&(x, _)| x)
        .collect();
    assert!(columns_below.len() <= 12, "{columns_below:?}");
    // The text is ink: pixels above the bar darker with the legend than without (its veil
    // only lightens), a few fully so, most in shades between (anti-aliased).
    let shade = |image: &Image, x, y| image.rgb(x, y).iter().map(|&c| c as i32).sum::<i32>();
    let darker: Vec<i32> = (0..h / 4)
        .flat_map(|y| (w / 2..w).map(move |x| (x, y)))
        .map(|(x, y)| shade(&bare, x, y) - shade(&radius, x, y))
        .filter(|&d| d > 30)
        .collect();
    let solid = darker.iter().filter(|&&d| d > 400).count();
    assert!(
        darker.len() > 60 && solid > 10,
        "{} darker, {solid} of them much",
        darker.len()
    );
    assert!(
        darker.len() > 2 * solid,
        "{} darker, {solid} of them much",
        darker.len()
    );
}

/// `mochi render FRAME -o PNG` in `d` at 96×72 pixels, one ray per pixel, on the cpu, without a
/// legend, with `extra` options: the picture, once the command succeeded.
fn small_picture(d: &Path, frame: &str, png: &str, extra: &[&str]) -> Image {
    let mut args = vec![
        "render",
        frame,
        "-o",
        png,
        "--size",
        "96x72",
        "--samples",
        "1",
        "--renderer",
        "cpu",
        "--no-legend",
    ];
    args.extend(extra);
    let run = mochi(&args, d);
    assert_eq!(run.0, Some(0), "{run:?}");
    read_png(&d.join(png)).unwrap()
}
