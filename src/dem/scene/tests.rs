//! The scene's reading, overriding, saving and building.

use super::*;
use crate::dem::model::{ContactLaw, RollingModel, TangentialModel};
use crate::scenes::Scene;
use crate::spheres::SphereSet;
use glam::DVec3;

/// `assignments` as overrides, which must parse.
fn given(assignments: &[impl AsRef<str>]) -> Overrides {
    Overrides::parse(assignments).expect("the overrides parse")
}

/// Significant digits of the number `token` (leading zeros, sign and exponent aside).
fn significant_digits(token: &str) -> usize {
    let mantissa = token.split(['e', 'E']).next().unwrap_or("");
    let digits: String = mantissa.chars().filter(char::is_ascii_digit).collect();
    digits.trim_start_matches('0').trim_end_matches('0').len()
}

#[test]
fn a_saved_scene_writes_f32_values_by_their_shortest_decimals_and_rebuilds_the_same_step() {
    let flags = SceneFlags::default();
    for sets in [
        &["spheres=300"][..],
        &["scene=rotating", "contact=linear", "spheres=50", "dt=2e-5"],
        &["scene=poly12", "contact=linear", "spheres=100"],
        &[
            "scene=freefall",
            "spheres=50",
            "box_lo=[-0.1, -0.3, -0.7]",
            "box_hi=[1.3, 1.7, 1.9]",
        ],
    ] {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let config = SceneConfig::load_new(None, &flags, &given(&sets)).unwrap();
        let start = config.build().unwrap();
        let saved = config.resolved(&start).to_toml();
        // No f32 widened to 16 or 17 digits (0.800000011920929): an f32 needs at most 9.
        let numbers = saved.split(|c: char| !(c.is_ascii_alphanumeric() || "+-.".contains(c)));
        for token in numbers.filter(|t| t.starts_with(|c: char| c.is_ascii_digit() || c == '-')) {
            assert!(significant_digits(token) <= 9, "{token} in\n{saved}");
        }
        // Read back, the scene builds the same step and saves the same text.
        let again = SceneConfig::parse(Some(&saved), None, &Overrides::default()).unwrap();
        let rebuilt = again.build().unwrap();
        assert_eq!(rebuilt.params, start.params, "{saved}");
        assert_eq!(again.resolved(&rebuilt).to_toml(), saved);
    }
}

#[test]
fn the_tangential_model_is_mindlin_unless_asked_and_mindlin_deresiewicz_is_for_hertz() {
    let flags = SceneFlags::default();
    let new = |sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        SceneConfig::load_new(None, &flags, &given(&sets))
    };
    let default = new(&["spheres=10"]).unwrap();
    assert_eq!(default.material.tangential_model, None);
    let m = default.material().unwrap();
    assert_eq!(m.tangential_model, TangentialModel::Mindlin);
    let md = new(&["spheres=10", "tangential_model=mindlin-deresiewicz"]).unwrap();
    let m = md.material().unwrap();
    assert_eq!(m.tangential_model, TangentialModel::MindlinDeresiewicz);
    let start = md.build().unwrap();
    assert!(start.params.friction.keeps_load());
    // Saved with the scene, so a checkpoint resumes under it.
    let saved = toml::to_string(&md.resolved(&start)).unwrap();
    assert!(
        saved.contains("tangential_model = \"mindlin-deresiewicz\""),
        "{saved}"
    );
    // An unknown model names the two.
    let e = new(&["tangential_model=mindlin-rescale"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("mindlin-deresiewicz"), "{e}");
    // The linear laws have no contact radius to follow.
    let sets = [
        "contact=linear",
        "friction=0.3",
        "tangential_model=mindlin-deresiewicz",
    ];
    let e = new(&sets)
        .and_then(|c| c.build())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("tangential_model") && e.contains("hertz-mindlin"),
        "{e}"
    );
    // Without friction it would act on nothing.
    let sets = ["friction=0", "tangential_model=mindlin-deresiewicz"];
    let e = new(&sets).unwrap_err().to_string();
    assert!(
        e.contains("tangential_model") && e.contains("friction"),
        "{e}"
    );
}

#[test]
fn overrides_take_toml_values_and_bare_words() {
    let c = SceneConfig::load(
        None,
        &given(&[
            "scene=poly12",
            "spheres = 2000",
            "gravity=[0, -9.81, 0]",
            "stiffness=3.5",
        ]),
    )
    .unwrap();
    assert_eq!(c.scene().name(), "poly12");
    assert_eq!(c.source.spheres().unwrap(), 2000);
    assert_eq!(c.domain.gravity, [0.0, -9.81, 0.0]);
    assert_eq!(c.material.stiffness, Some(Stiffness::Fixed(3.5)));
}

#[test]
fn unknown_fields_and_bad_values_are_errors() {
    let e = SceneConfig::load(None, &given(&["sphers=10"])).unwrap_err();
    assert!(e.to_string().contains("sphers"), "{e}");
    let e = SceneConfig::load(None, &given(&["spheres=-3"])).unwrap_err();
    assert!(
        e.to_string().contains("spheres") || e.to_string().contains("-3"),
        "{e}"
    );
    let e = Overrides::parse(&["steps=18446744073709551615"]).unwrap_err();
    assert!(e.to_string().contains("outside the range"), "{e}");
    let e = Overrides::parse(&["no equals sign"]).unwrap_err();
    assert!(e.to_string().contains("key=value"), "{e}");
    let e = SceneConfig::load(None, &given(&["scene=teapot"])).unwrap_err();
    assert!(e.to_string().contains("teapot"), "{e}");
    let e = SceneConfig::load(None, &given(&["frcition=0.2"])).unwrap_err();
    assert!(e.to_string().contains("did you mean friction?"), "{e}");
    let e = SceneConfig::load(None, &given(&["sourse.spheres=10"])).unwrap_err();
    assert!(e.to_string().contains("did you mean source?"), "{e}");
    let e = SceneConfig::load(None, &given(&["material.frcition=0.2"])).unwrap_err();
    assert!(e.to_string().contains("unknown field `frcition`"), "{e}");
    let set = Overrides::from_table(toml::toml! { frcition = 0.2 });
    let e = SceneConfig::load(None, &set).unwrap_err();
    assert!(e.to_string().contains("did you mean friction?"), "{e}");
}

#[test]
fn unknown_scenes_and_modes_are_errors_listing_the_names() {
    let e =
        SceneConfig::parse(Some("scene = \"teapot\""), None, &Overrides::default()).unwrap_err();
    let e = e.to_string();
    assert!(
        e.contains(
            "unknown scene \"teapot\": use freefall, slab, poly1.2, poly12, poly120, \
                 polylog, pour, rotating, mesh, input, hopper, drum, agglomerate or gravel"
        ),
        "{e}"
    );
    let e = SceneConfig::load(None, &given(&["mode=fast"])).unwrap_err();
    let e = e.to_string();
    assert!(
        e.contains("unknown value \"fast\": use mochi or nns"),
        "{e}"
    );
}

#[test]
fn each_scene_and_mode_has_one_name_in_toml_and_on_the_command_line() {
    use crate::names::Named;
    for scene in SceneKind::ALL {
        let c = SceneConfig::load(None, &given(&[format!("scene={}", scene.name())])).unwrap();
        assert_eq!(c.scene(), scene);
        assert!(c.to_toml().contains(&format!("scene = \"{scene}\"")));
    }
    let generated = SceneKind::ALL.iter().filter_map(|s| match s {
        SceneKind::Generated(scene) => Some(*scene),
        _ => None,
    });
    assert!(generated.eq(Scene::ALL.iter().copied()));
    for &mode in ProxyMode::ALL {
        let name = mode.name();
        assert_eq!(serde_json::to_string(&mode).unwrap(), format!("\"{name}\""));
        let c = SceneConfig::load(None, &given(&[format!("mode={name}")])).unwrap();
        assert_eq!(c.run.mode, mode);
        assert!(c.to_toml().contains(&format!("mode = \"{name}\"")));
    }
}

#[test]
fn flags_apply_over_the_file_and_set_over_the_flags() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("s.toml");
    std::fs::write(&file, "scene = \"poly12\"\nspheres = 300\nsteps = 7\n").unwrap();
    let flags = SceneFlags {
        scene: Some(SceneKind::Rotating),
        spheres: Some(200),
        mode: Some(ProxyMode::Nns),
        ..SceneFlags::default()
    };
    let c = SceneConfig::load_new(Some(&file), &flags, &given(&["spheres=100"])).unwrap();
    assert_eq!(
        (
            c.scene(),
            c.source.spheres().unwrap(),
            c.run.steps,
            c.run.mode
        ),
        (SceneKind::Rotating, 100, 7, ProxyMode::Nns)
    );
    // A flag the scene does not use is refused, naming the flag.
    let flags = SceneFlags {
        spheres: Some(200),
        mesh: Some("m.obj".into()),
        scene: Some(SceneKind::Mesh),
        ..SceneFlags::default()
    };
    let e = SceneConfig::load_new(None, &flags, &Overrides::default()).unwrap_err();
    assert!(e.to_string().contains("-n/--set spheres"), "{e}");
}

#[cfg(unix)]
#[test]
fn a_path_toml_cannot_hold_is_a_clear_error() {
    use std::os::unix::ffi::OsStrExt;
    let flags = SceneFlags {
        scene: Some(SceneKind::Input),
        input: Some(std::ffi::OsStr::from_bytes(b"bad\xff.csv").into()),
        ..SceneFlags::default()
    };
    let e = SceneConfig::load_new(None, &flags, &Overrides::default()).unwrap_err();
    assert!(
        e.to_string().contains("cannot be written in TOML: path"),
        "{e}"
    );
}

#[test]
fn a_checkpoint_scene_of_the_flat_format_reads_as_saved_and_is_written_in_tables() {
    let saved = "scene = \"rotating\"\nspheres = 64\nseed = 3\nsteps = 10\ndt = 0.0001\n\
                 box_lo = [0.0, 0.0, 0.0]\nbox_hi = [1.0, 1.0, 1.0]\n\
                 gravity = [0.0, 0.0, -9.81]\ngravity_spin = 0.7853981852531433\n\
                 density = 500.0\nrestitution = 0.5\nstiffness = 2.0\nmode = \"nns\"\n\
                 frame_every = 5\ncsv = false\nmesh_radius = 0.005\n\
                 mesh_mixed = false\nmesh_size = 0.818\nmesh_copies = 1\n";
    let resume = |saved: &str| {
        SceneConfig::resume(
            saved,
            Path::new("c.bin"),
            &SceneFlags::default(),
            &Overrides::default(),
        )
    };
    let c = resume(saved).unwrap();
    assert_eq!(
        (c.scene(), c.run.mode),
        (SceneKind::Rotating, ProxyMode::Nns)
    );
    assert_eq!((c.source.spheres(), c.run.steps), (Some(64), 10));
    // Saved before hertz-mindlin became the default, without a contact law: linear, and
    // written out from now on. The mesh keys that format wrote for every scene say nothing.
    assert_eq!(c.material.contact, ContactKind::Linear);
    let tables = "[run]\nsteps = 10\ndt = 0.0001\nmode = \"nns\"\nframe_every = 5\ncsv = false\n\
                  frame_pieces = false\ncheckpoint_pieces = false\n\n\
                  [source]\nscene = \"rotating\"\nspheres = 64\nseed = 3\n\n\
                  [domain]\nbox_lo = [0.0, 0.0, 0.0]\nbox_hi = [1.0, 1.0, 1.0]\n\
                  gravity = [0.0, 0.0, -9.81]\ngravity_spin = 0.7853981852531433\n\n\
                  [material]\ncontact = \"linear\"\ndensity = 500.0\nrestitution = 0.5\n\
                  stiffness = 2.0\n";
    assert_eq!(c.to_toml(), tables);
    assert_eq!(resume(tables).unwrap(), c);
    // The flat format's keys of another scene: an input scene's spheres and seed too.
    let input = saved
        .replace("\"rotating\"", "\"input\"")
        .replace("gravity_spin", "input = \"in.csv\"\ngravity_spin");
    let c = resume(&input).unwrap();
    assert_eq!(c.source.file(), Some(Path::new("in.csv")));
    // Names were always read in any case.
    let c = SceneConfig::parse(
        Some("scene = \"Poly1.2\"\nmode = \"NNS\""),
        None,
        &Overrides::default(),
    )
    .unwrap();
    assert_eq!(
        (c.scene(), c.run.mode),
        (SceneKind::Generated(Scene::Poly1_2), ProxyMode::Nns)
    );
}

#[test]
fn a_scene_round_trips_through_toml() {
    let mut c = SceneConfig::default();
    c.run.dt = Some(2e-5);
    c.material.stiffness = Some(Stiffness::Fixed(10.0));
    let back: SceneConfig = toml::from_str(&c.to_toml()).unwrap();
    assert_eq!(back, c);
    // Every kind of scene, its own keys and all.
    for kind in SceneKind::ALL {
        let c = SceneConfig {
            source: Source::sized(kind, 7, 3),
            ..SceneConfig::default()
        };
        let back: SceneConfig = toml::from_str(&c.to_toml()).unwrap();
        assert_eq!(back, c, "{}", c.to_toml());
    }
}

#[test]
fn the_mesh_scene_fills_copies_side_by_side_without_overlaps() {
    let c = SceneConfig::load(
        None,
        &given(&[
            "scene=mesh",
            "contact=linear",
            "mesh_radius=0.02",
            "mesh_size=0.5",
            "mesh_copies=3",
            "mesh_mixed=true",
        ]),
    )
    .unwrap();
    let s = c.build().unwrap();
    let n = s.particles.len();
    assert!(n > 300 && n.is_multiple_of(3), "{n}");
    let spheres = SphereSet::new(s.particles.positions.clone(), s.particles.radii.clone()).unwrap();
    assert!(crate::oracle::brute_force_pairs(&spheres).is_empty());
    assert!(s.particles.radii.contains(&0.01));
    assert_eq!(s.params.dt, 2.5e-5);
    let bad = SceneConfig::load(None, &given(&["scene=mesh", "mesh=\"nope.obj\""])).unwrap();
    assert!(bad.build().unwrap_err().to_string().contains("nope.obj"));
}

#[test]
fn new_scenes_are_hertz_mindlin_with_the_documented_material() {
    let c = SceneConfig::load(None, &Overrides::default()).unwrap();
    assert_eq!(c.scene(), SceneKind::Generated(Scene::Pour));
    let m = c.material().unwrap();
    assert_eq!(
        m.contact,
        ContactLaw::HertzMindlin {
            young_modulus: 1e7,
            poisson_ratio: 0.3
        }
    );
    assert_eq!((m.friction, m.wall_friction), (0.5, None));
    assert_eq!(
        (m.rolling_friction, m.rolling_model),
        (0.1, RollingModel::Epsd)
    );
    // A scene file without `contact` is Hertz–Mindlin too, and says so when saved.
    let c = SceneConfig::parse(Some("scene = \"slab\""), None, &Overrides::default()).unwrap();
    assert!(
        c.to_toml().contains("contact = \"hertz-mindlin\""),
        "{}",
        c.to_toml()
    );
    let saved = SceneConfig::resume(
        &c.to_toml(),
        Path::new("c.bin"),
        &SceneFlags::default(),
        &Overrides::default(),
    )
    .unwrap();
    assert_eq!(saved.material.contact, ContactKind::HertzMindlin);
}

#[test]
fn rotating_spins_gravity_a_quarter_pi_per_second() {
    let c = SceneConfig::load(None, &given(&["scene=rotating", "spheres=1000"])).unwrap();
    let s = c.build().unwrap();
    assert!((s.params.gravity_spin as f64 - 0.25 * std::f64::consts::PI).abs() < 1e-6);
}

#[test]
fn wall_tables_read_their_meshes_and_name_the_file_of_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("floor.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let scene = dir.path().join("scene.toml");
    let text = "scene = \"freefall\"\nspheres = 8\nbox_walls = false\n\n[[wall]]\n\
                    mesh = \"floor.obj\"\nscale = 2.0\nrotate = { axis = [1, 0, 0], degrees = 10 }\n\
                    omega = 1.5\naxis = [0, 1, 0]\n";
    let c = SceneConfig::parse(Some(text), Some(&scene), &Overrides::default()).unwrap();
    assert_eq!(c.wall[0].mesh, obj);
    let start = c.build().unwrap();
    assert!(!start.walls.box_walls);
    assert_eq!(start.walls.meshes.len(), 1);
    assert_eq!(start.walls.meshes[0].motion.omega, 1.5);
    // Saved and read back (a checkpoint's scene) the same.
    let back: SceneConfig = toml::from_str(&c.resolved(&start).to_toml()).unwrap();
    assert_eq!(back.wall, c.wall);
    assert!(!back.domain.box_walls);
    // A file that is not there, a key no wall has, a bad scale: one error each, naming it.
    let missing = text.replace("floor.obj", "nowhere.obj");
    let e = SceneConfig::parse(Some(&missing), Some(&scene), &Overrides::default())
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("nowhere.obj"), "{e}");
    let e = SceneConfig::parse(
        Some(&format!("{text}colour = 1\n")),
        Some(&scene),
        &Overrides::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("colour"), "{e}");
    let e = SceneConfig::parse(
        Some(&text.replace("2.0", "-1.0")),
        Some(&scene),
        &Overrides::default(),
    )
    .unwrap()
    .build()
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("wall 0") && e.contains("floor.obj") && e.contains("scale"),
        "{e}"
    );
}

#[test]
fn dotted_overrides_set_one_field_of_a_table_and_name_what_is_missing() {
    let text = "scene = \"freefall\"\nspheres = 8\n\n[[inflow]]\ncenter = [0.5, 0.5, 0.9]\n\
                    radius = 0.1\nrate = 100\nsphere_radius = 0.002\n\n[[inflow]]\n\
                    lo = [0.1, 0.1, 0.8]\nhi = [0.2, 0.2, 0.9]\nrate = 50\nsphere_radius = 0.003\n";
    let c = SceneConfig::parse(Some(text), None, &given(&["inflow.1.rate=75"])).unwrap();
    assert_eq!(
        (c.inflow[0].rate, c.inflow[1].rate),
        (Some(100.0), Some(75.0))
    );
    assert_eq!(
        c.inflow[1].sphere_radius,
        Some(0.003),
        "the table's other fields stay"
    );
    // In order, whole fields and paths alike: the later wins.
    let c =
        SceneConfig::parse(Some(text), None, &given(&["inflow.0.rate=7", "spheres=9"])).unwrap();
    assert_eq!(
        (c.inflow[0].rate, c.source.spheres().unwrap()),
        (Some(7.0), 9)
    );
    let refused = |sets: &[&str]| {
        SceneConfig::parse(Some(text), None, &given(sets))
            .unwrap_err()
            .to_string()
    };
    let e = refused(&["inflow.2.rate=1"]);
    assert!(
        e.contains("--set inflow.2.rate") && e.contains("2 inflow tables"),
        "{e}"
    );
    assert!(e.contains("inflow.0 to inflow.1"), "{e}");
    let e = refused(&["inflow.rate=1"]);
    assert!(e.contains("the part after it is an index"), "{e}");
    let e = refused(&["inflow.0=1"]);
    assert!(e.contains("name the field of it to set"), "{e}");
    let e = refused(&["outflow.0.lo=[0, 0, 0]"]);
    assert!(e.contains("there are no outflow tables here"), "{e}");
    let e = refused(&["spheres.x=1"]);
    assert!(e.contains("spheres is 8, not a table"), "{e}");
    // A path into no table of the scene is refused by the scene's fields, as a key is.
    let e = refused(&["inflow.0.colour=1"]);
    assert!(e.contains("colour"), "{e}");
    let e = Overrides::parse(&["0.rate=1"]).unwrap_err().to_string();
    assert!(e.contains("is not a field name"), "{e}");
    let e = Overrides::parse(&["inflow..rate=1"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("is not a field name"), "{e}");
}

#[test]
fn inflow_and_outflow_tables_make_the_flows_and_refuse_what_is_ambiguous() {
    let text = "scene = \"freefall\"\nspheres = 8\nbox_walls = false\n\n[[inflow]]\n\
                    center = [0.5, 0.5, 0.9]\nradius = 0.1\nmass_rate = 0.01\n\
                    sphere_radius = 0.002\n\n[[outflow]]\nlo = [0, 0, 0]\nhi = [1, 1, 0.1]\n";
    let c = SceneConfig::parse(Some(text), None, &Overrides::default()).unwrap();
    let start = c.build().unwrap();
    let flow = &start.flow;
    assert_eq!((flow.inflows.len(), flow.outflows.len()), (1, 1));
    // Without the box walls, the floor of the box drains too.
    assert_eq!(flow.floor, Some(start.params.box_lo[2]));
    // 0.01 kg/s of 2 mm spheres at 500 kg/m³.
    let each = 500.0 * 4.0 / 3.0 * std::f64::consts::PI * 0.002f64.powi(3);
    assert!((flow.inflows[0].rate * each / 0.01 - 1.0).abs() < 1e-9);
    // The inserted spheres' radius sets the time step when smaller than the scene's.
    assert!(start.params.dt_limit > 0.0);
    let both = text.replace("mass_rate = 0.01", "mass_rate = 0.01\nrate = 5");
    let e = SceneConfig::parse(Some(&both), None, &Overrides::default())
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("inflow 0") && e.contains("one of the two"),
        "{e}"
    );
    let inverted = text.replace("hi = [1, 1, 0.1]", "hi = [1, 1, -0.1]");
    let e = SceneConfig::parse(Some(&inverted), None, &Overrides::default())
        .unwrap()
        .build()
        .unwrap_err()
        .to_string();
    assert!(e.contains("outflow 0"), "{e}");
}

#[test]
fn the_hopper_and_the_drum_come_with_their_walls_inside_their_box() {
    for (scene, walls, outflows) in [("hopper", 2, 1), ("drum", 1, 0)] {
        let over = [format!("scene={scene}"), "spheres=300".into()];
        let c = SceneConfig::load(None, &given(&over)).unwrap();
        let start = c.build().unwrap();
        assert_eq!(start.particles.len(), 300);
        assert_eq!(start.walls.meshes.len(), walls, "{scene}");
        assert_eq!(start.flow.outflows.len(), outflows, "{scene}");
        let set = SphereSet::new(
            start.particles.positions.clone(),
            start.particles.radii.clone(),
        )
        .unwrap();
        let pairs = crate::oracle::brute_force_pairs(&set);
        assert!(pairs.is_empty(), "{scene}: the filled spheres overlap");
        // No sphere touches a wall at t = 0.
        let poses = start.walls.poses_at(0.0);
        for (wall, pose) in start.walls.meshes.iter().zip(&poses) {
            for (c, &r) in start.particles.positions.iter().zip(&start.particles.radii) {
                let mut touching = crate::dem::walls::Touches::default();
                crate::dem::walls::touches(
                    &wall.triangles,
                    pose,
                    glam::Vec3::from(*c),
                    (r, 0.0),
                    &mut touching,
                );
                assert!(
                    touching.found.is_empty(),
                    "{scene}: a sphere at {c:?} touches {}",
                    wall.name
                );
            }
        }
    }
    // A drum of few sides holds its spheres inside its polygon: each lies on the axis's side
    // of every side's plane, by its radius at least.
    for sides in 3..=6 {
        let over = ["scene=drum".into(), format!("drum_sides={sides}")];
        let start = SceneConfig::load(None, &given(&over))
            .unwrap()
            .build()
            .unwrap();
        let tube = start.walls.triangles_at(0.0);
        for (c, &r) in start.particles.positions.iter().zip(&start.particles.radii) {
            let c = glam::Vec3::from(*c);
            let axis = glam::Vec3::new(0.0, c.y, 0.0);
            for [a, b, d] in tube.iter().map(|t| t.map(glam::Vec3::from)) {
                let n = (b - a).cross(d - a).normalize();
                let (sphere, centre) = (n.dot(c - a), n.dot(axis - a));
                assert!(
                    sphere * centre.signum() >= r,
                    "{sides} sides: a sphere at {c} is outside the drum"
                );
            }
        }
    }
    // However few the spheres or wide the orifice, a hopper has room for them.
    for over in [
        ["spheres=10", "hopper_orifice=0.04"],
        ["spheres=4000", "hopper_orifice=10"],
    ] {
        let over: Vec<String> = ["scene=hopper"]
            .iter()
            .chain(&over)
            .map(|s| s.to_string())
            .collect();
        let start = SceneConfig::load(None, &given(&over)).unwrap().build();
        assert!(start.is_ok(), "{over:?}: {:?}", start.err());
    }
    let e = SceneConfig::load_new(
        None,
        &SceneFlags::default(),
        &given(&["scene=drum", "hopper_angle=30"]),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("hopper_angle"), "{e}");
}

/// The `[[material]]` and `[[material_pair]]` tables as a scene reads them (`material_spec`).
mod material_tables {
    use crate::dem::model::{ContactLaw, StepParams};
    use crate::dem::scene::{Overrides, SceneConfig};

    fn scene(text: &str) -> crate::error::Result<SceneConfig> {
        SceneConfig::parse(Some(text), None, &Overrides::default())
    }

    const TWO: &str = r#"
        friction = 0.4
        [[material]]
        name = "glass"
        young_modulus = 6.3e10
        poisson_ratio = 0.24
        density = 2500
        restitution = 0.9
        rolling_friction = 0.01
        [[material]]
        name = "steel"
        young_modulus = 2.0e11
        poisson_ratio = 0.3
        density = 7800
        friction = 0.3
        [[material_pair]]
        materials = ["steel", "glass"]
        restitution = 0.8
    "#;

    #[test]
    fn material_tables_take_the_top_level_keys_as_defaults_and_pairs_override_the_mixing() {
        let s = scene(TWO).unwrap();
        let m = s.materials().unwrap();
        assert_eq!(m.names, ["glass", "steel"]);
        let (glass, steel) = (&m.list[0], &m.list[1]);
        assert_eq!((glass.friction, steel.friction), (0.4, 0.3));
        assert_eq!((glass.density, steel.density), (2500.0, 7800.0));
        // The scene's default restitution (0.5) where a table gives none.
        assert_eq!((glass.restitution, steel.restitution), (0.9, 0.5));
        assert!(matches!(
            steel.contact,
            ContactLaw::HertzMindlin { young_modulus, .. } if young_modulus == 2.0e11
        ));
        // Restitution: the pair's own; friction and rolling friction: the smaller.
        // (Steel's rolling friction is the scene's default, 0.1.)
        assert_eq!(m.coefficients(0, Some(1)), (0.8, 0.3, 0.01));
        assert_eq!(m.coefficients(1, Some(0)), (0.8, 0.3, 0.01));
        assert_eq!(m.coefficients(0, Some(0)), (0.9, 0.4, 0.01));
        // A rigid wall: the sphere's own, friction the scene's wall friction (here μ).
        assert_eq!(m.coefficients(1, None), (0.5, 0.3, 0.1));
    }

    #[test]
    fn the_table_mixes_the_moduli_of_both_bodies_and_the_time_step_follows_the_stiffest() {
        let s = scene(TWO).unwrap();
        let m = s.materials().unwrap();
        let p =
            StepParams::with_materials(&m, Some(1), 1e-7, [0.0; 3], [1.0; 3], [0.0; 3], 0.0, 0.001)
                .unwrap();
        let t = &p.materials;
        assert_eq!((t.count, t.laws.len(), p.box_column), (2, 6, 1));
        let c = |e: f64, nu: f64| (1.0 - nu * nu) / e;
        let mixed = 1.0 / (c(6.3e10, 0.24) + c(2.0e11, 0.3));
        assert_eq!(t.law(0, 1).e_star, mixed as f32);
        assert_eq!(t.law(1, 0), t.law(0, 1));
        assert_eq!(t.law(0, 0).e_star, (1.0 / (2.0 * c(6.3e10, 0.24))) as f32);
        assert_eq!(
            t.law(0, 2).e_star,
            (1.0 / c(6.3e10, 0.24)) as f32,
            "rigid wall"
        );
        assert_eq!((t.law(0, 1).sliding, t.law(0, 0).rolling), (0.3, 0.01));
        assert_eq!(t.densities, [2500.0, 7800.0]);
        // The shorter Rayleigh time (glass's, by 1%) sets the limit.
        let rayleigh = |e: f64, nu: f64, rho: f64| {
            crate::dem::model::time_step::rayleigh_time(0.001, rho, e, nu)
        };
        let limit = 0.5 * rayleigh(6.3e10, 0.24, 2500.0);
        assert!(rayleigh(6.3e10, 0.24, 2500.0) < rayleigh(2.0e11, 0.3, 7800.0));
        assert!(
            (p.dt_limit as f64 / limit - 1.0).abs() < 1e-6,
            "{} {limit}",
            p.dt_limit
        );
        let e = StepParams::with_materials(
            &m,
            None,
            1.01 * limit,
            [0.0; 3],
            [1.0; 3],
            [0.0; 3],
            0.0,
            0.001,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("\"glass\""), "{e}");
    }

    #[test]
    fn bad_material_tables_are_one_clear_error() {
        let err = |text: &str| {
            let s = scene(text).and_then(|s| s.build().map(|_| s));
            s.unwrap_err().to_string()
        };
        let e = err("[[material]]\nname = \"a\"\n[[material]]\nname = \"a\"\n");
        assert!(e.contains("\"a\" is given twice"), "{e}");
        let e = err("box_material = \"b\"\n[[material]]\nname = \"a\"\n");
        assert!(
            e.contains("box_material") && e.contains("\"b\"") && e.contains("\"a\""),
            "{e}"
        );
        let e = err("box_material = \"b\"\n");
        assert!(e.contains("no [[materials]] tables"), "{e}");
        let e = err("[[material]]\nname = \"a\"\nrestitution = 1.5\n[[material]]\nname = \"b\"\n");
        assert!(
            e.contains("material \"a\"") && e.contains("restitution"),
            "{e}"
        );
        let e = err("contact = \"linear\"\n[[material]]\nname = \"a\"\nyoung_modulus = 1e9\n");
        assert!(e.contains("hertz-mindlin"), "{e}");
        let e = err("[[material]]\nname = \"a\"\n[[material_pair]]\nmaterials = [\"a\", \"c\"]\n");
        assert!(e.contains("\"c\""), "{e}");
        let e = err("[[material]]\nname = \"a\"\ncolour = 3\n");
        assert!(e.contains("colour"), "{e}");
        let many: String = (0..257)
            .map(|k| format!("[[material]]\nname = \"m{k}\"\n"))
            .collect();
        assert!(err(&many).contains("at most 256"));
    }
}

#[test]
fn between_steps_the_materials_and_gravity_change_and_the_rest_is_refused() {
    let flags = SceneFlags::default();
    let config =
        SceneConfig::load_new(None, &flags, &given(&["scene=pour", "spheres=100"])).unwrap();
    let changed = config
        .changed(&given(&["friction=0.1", "gravity=[0, 0, -1]", "steps=5"]))
        .unwrap();
    assert_eq!(changed.material.friction, Some(0.1));
    assert_eq!(changed.domain.gravity, [0.0, 0.0, -1.0]);
    for (set, key) in [
        ("spheres=50", "scene key source.spheres (spheres)"),
        ("mode=\"nns\"", "scene key run.mode (mode)"),
        ("box_hi=[2, 2, 2]", "scene key domain.box_hi (box_hi)"),
    ] {
        let e = config.changed(&given(&[set])).unwrap_err().to_string();
        assert!(
            e.contains(key) && e.contains("cannot change between steps"),
            "{e}"
        );
    }
    // Materials keep their names in their order: the spheres' indices name them.
    let two = "materials=[{name = \"a\"}, {name = \"b\"}]";
    let config =
        SceneConfig::load_new(None, &flags, &given(&["scene=pour", "spheres=100", two])).unwrap();
    let denser = "materials=[{name = \"a\", density = 900}, {name = \"b\"}]";
    assert_eq!(
        config.changed(&given(&[denser])).unwrap().materials[0].density,
        Some(900.0)
    );
    let renamed = "materials=[{name = \"b\"}, {name = \"a\"}]";
    let e = config.changed(&given(&[renamed])).unwrap_err().to_string();
    assert!(e.contains("scene key materials"), "{e}");
}

#[test]
fn cohesion_takes_a_surface_energy_with_hertz_mindlin_and_nothing_else() {
    let flags = SceneFlags::default();
    let build = |sets: &[&str]| {
        let mut all = vec!["scene=freefall", "spheres=20"];
        all.extend_from_slice(sets);
        SceneConfig::load_new(None, &flags, &given(&all)).and_then(|c| c.build())
    };
    let start = build(&["cohesion=\"jkr\"", "surface_energy=0.05"]).unwrap();
    assert!(start.params.friction.cohesive && start.params.friction.has_history());
    assert_eq!(start.params.materials.law(0, 0).adhesion, 0.05);
    assert!(!build(&[]).unwrap().params.friction.cohesive);
    let wet = build(&[
        "cohesion=\"capillary\"",
        "liquid_volume=1e-12",
        "contact_angle=60",
    ])
    .unwrap();
    let bridge = wet.params.bridge.expect("a bridge");
    // Two spheres and a sphere on a rigid wall alike.
    for column in [0, 1] {
        let pair = wet.params.materials.bridge(0, column);
        assert!(
            (pair.tension - 0.036).abs() < 1e-6,
            "water's γ at 60°: {}",
            pair.tension
        );
        assert!((pair.rupture - (1.0 + std::f32::consts::PI / 6.0) * 1e-4).abs() < 1e-9);
    }
    assert_eq!(bridge.viscosity, 0.0);
    let viscous = build(&[
        "cohesion=\"capillary\"",
        "liquid_volume=1e-12",
        "liquid_viscosity=0.001",
    ])
    .unwrap();
    assert_eq!(viscous.params.bridge.expect("a bridge").viscosity, 0.001);
    assert!(viscous.params.describe().contains(", η 0.001 Pa·s)"));
    // A viscous liquid's lubrication force limits the time step: the default stays under it,
    // a larger one given is refused.
    let thick = [
        "cohesion=\"capillary\"",
        "liquid_volume=1e-12",
        "liquid_viscosity=50",
    ];
    let rule = build(&thick[..2]).unwrap().params.dt;
    let limited = build(&thick).unwrap().params.dt;
    assert!(
        limited < 0.1 * rule,
        "dt {limited} s, the Rayleigh rule's {rule} s"
    );
    let too_large = format!("dt={}", 2.0 * limited);
    let refused = build(&[thick[0], thick[1], thick[2], &too_large]).expect_err("refused");
    assert!(
        refused.to_string().contains("lubrication force"),
        "{refused}"
    );
    // The run's summary line names the law.
    assert!(
        start
            .params
            .describe()
            .ends_with("| cohesion jkr (Γ up to 0.05 J/m²)")
    );
    assert!(
        wet.params
            .describe()
            .contains("| cohesion capillary (V 1e-12 m³")
    );
    assert!(!build(&[]).unwrap().params.describe().contains("cohesion"));
    let simple = build(&["cohesion=\"sjkr\"", "cohesion_energy_density=1e5"]).unwrap();
    assert!(simple.params.adheres() && simple.params.cohesion_density == 1e5);
    assert!(wet.params.friction.cohesive);
    for (sets, words) in [
        (&["cohesion=\"jkr\""][..], "needs surface_energy"),
        (&["surface_energy=0.05"], "applies to cohesion = \"jkr\""),
        (
            &[
                "cohesion=\"jkr\"",
                "surface_energy=0.05",
                "contact=\"linear\"",
            ],
            "hertz-mindlin",
        ),
        (&["cohesion=\"jkr\"", "surface_energy=-1"], "positive"),
        (&["cohesion=\"capillary\""], "needs liquid_volume"),
        (&["liquid_volume=1e-12"], "give it as well"),
        (
            &[
                "cohesion=\"capillary\"",
                "liquid_volume=1e-12",
                "contact_angle=95",
            ],
            "90°",
        ),
        (
            &["cohesion=\"jkr\"", "liquid_volume=1e-12"],
            "cohesion = \"capillary\"",
        ),
        (&["liquid_viscosity=0.001"], "cohesion = \"capillary\""),
        (
            &[
                "cohesion=\"capillary\"",
                "liquid_volume=1e-12",
                "liquid_viscosity=-1",
            ],
            "liquid_viscosity must be 0 or a positive",
        ),
        (&["cohesion=\"sjkr\""], "needs cohesion_energy_density"),
        (&["cohesion_energy_density=1e5"], "cohesion = \"sjkr\""),
    ] {
        let e = build(sets).expect_err("refused").to_string();
        assert!(e.contains(words), "{sets:?}: {e}");
    }
}

#[test]
fn an_agglomerate_is_a_ball_of_touching_grains_bonded_by_water_moving_down() {
    let config = SceneConfig::parse(
        Some("scene = \"agglomerate\"\nspheres = 300\nagglomerate_speed = 0.4"),
        None,
        &Overrides::default(),
    )
    .unwrap();
    let start = config.build().unwrap();
    let p = &start.particles;
    assert_eq!(p.len(), 300);
    assert!(p.velocities.iter().all(|v| *v == [0.0, 0.0, -0.4]));
    // Every grain touches a neighbour (pressed 1e-3 of a radius), and most have 12 or near it.
    let r = 1e-3f32;
    let touching = |i: usize| {
        (0..p.len())
            .filter(|&j| j != i)
            .filter(|&j| {
                let d: f32 = (0..3)
                    .map(|a| (p.positions[i][a] - p.positions[j][a]).powi(2))
                    .sum();
                d.sqrt() < 2.0 * r
            })
            .count()
    };
    let counts: Vec<usize> = (0..p.len()).map(touching).collect();
    assert!(counts.iter().all(|&c| c >= 3), "a loose grain: {counts:?}");
    assert!(counts.iter().filter(|&&c| c == 12).count() > 50);
    // Its lowest grain half a radius above the floor.
    let lowest = p.positions.iter().map(|c| c[2]).fold(f32::MAX, f32::min);
    assert!(
        (lowest - 1.5 * r).abs() < 1e-6,
        "the lowest grain half a radius up: {lowest}"
    );
    // Bonded by water by default (1 nl between 1 mm grains); a material's own cohesion wins.
    let bridge = start.params.bridge.expect("liquid bridges");
    assert!((bridge.volume as f64 / 1.0053e-12 - 1.0).abs() < 1e-3);
    let resolved = config.resolved(&start);
    assert_eq!(resolved.material.cohesion, Some(CohesionKind::Capillary));
    let jkr = SceneConfig::parse(
        Some("scene = \"agglomerate\"\ncohesion = \"jkr\"\nsurface_energy = 0.1"),
        None,
        &Overrides::default(),
    )
    .unwrap();
    let start = jkr.build().unwrap();
    assert!(start.params.bridge.is_none() && start.params.friction.cohesive);
}

#[test]
fn each_material_and_pair_of_materials_may_give_its_own_surface_energy() {
    let scene = |pair: &str| {
        format!(
            "scene = \"freefall\"\nspheres = 20\ncohesion = \"jkr\"\nsurface_energy = 0.04\n\
             [[materials]]\nname = \"a\"\n[[materials]]\nname = \"b\"\nsurface_energy = 0.09\n\
             [[materials]]\nname = \"c\"\nsurface_energy = 0.0\n{pair}"
        )
    };
    let law = |text: &str| {
        let config = SceneConfig::parse(Some(text), None, &Overrides::default()).unwrap();
        config.build().map(|s| s.params.materials)
    };
    let t = law(&scene("")).unwrap();
    // Its own Γ with itself and with a rigid wall; the geometric mean with another material.
    let wall = t.count as u32;
    assert_eq!(t.law(0, 0).adhesion, 0.04);
    assert_eq!(t.law(1, 1).adhesion, 0.09);
    assert_eq!(t.law(1, wall).adhesion, 0.09);
    assert!((t.law(0, 1).adhesion - 0.06).abs() < 1e-8);
    assert_eq!(t.law(2, 0).adhesion, 0.0);
    // A pair's own Γ, both ways.
    let paired = "[[material_pairs]]\nmaterials = [\"a\", \"c\"]\nsurface_energy = 0.5\n";
    let t = law(&scene(paired)).unwrap();
    assert_eq!((t.law(0, 2).adhesion, t.law(2, 0).adhesion), (0.5, 0.5));
    assert_eq!(t.law(2, 2).adhesion, 0.0);
    // Refused without JKR, and out of range.
    let dry = "scene = \"freefall\"\nspheres = 20\n[[materials]]\nname = \"a\"\n\
               surface_energy = 0.1\n";
    let e = law(dry).unwrap_err().to_string();
    assert!(e.contains("applies to cohesion = \"jkr\""), "{e}");
    let negative = "[[material_pairs]]\nmaterials = [\"a\", \"b\"]\nsurface_energy = -1\n";
    let e = law(&scene(negative)).unwrap_err().to_string();
    assert!(e.contains("surface_energy = -1, out of range"), "{e}");
}

#[test]
fn each_material_and_pair_of_materials_may_give_its_own_contact_angle() {
    let scene = |pair: &str| {
        format!(
            "scene = \"freefall\"\nspheres = 20\ncohesion = \"capillary\"\n\
             liquid_volume = 1e-12\nsurface_tension = 0.05\ncontact_angle = 20\n\
             [[materials]]\nname = \"a\"\n[[materials]]\nname = \"b\"\ncontact_angle = 60\n\
             [[materials]]\nname = \"c\"\ncontact_angle = 0\n{pair}"
        )
    };
    let table = |text: &str| {
        let config = SceneConfig::parse(Some(text), None, &Overrides::default()).unwrap();
        config.build().map(|s| s.params.materials)
    };
    let t = table(&scene("")).unwrap();
    let wall = t.count as u32;
    let (gamma, v3) = (0.05f64, 1e-4f64);
    let expect = |a: f64, b: f64| {
        let (a, b) = (a.to_radians(), b.to_radians());
        (
            (gamma * (a.cos() + b.cos()) / 2.0) as f32,
            ((1.0 + (a + b) / 4.0) * v3) as f32,
        )
    };
    let of = |a: u32, b: u32| (t.bridge(a, b).tension, t.bridge(a, b).rupture);
    // Its own angle with itself and with a rigid wall (the scene's where it gives none).
    assert_eq!(of(0, 0), expect(20.0, 20.0));
    assert_eq!(of(1, 1), expect(60.0, 60.0));
    assert_eq!(of(1, wall), expect(60.0, 60.0));
    assert_eq!(of(2, 2), (0.05, 1e-4));
    // Two materials: the mean of the cosines pulls, the mean angle ruptures; both ways alike.
    assert_eq!(of(1, 2), expect(60.0, 0.0));
    assert_eq!(of(2, 1), of(1, 2));
    assert!((t.bridge(1, 2).tension - 0.0375).abs() < 1e-8);
    // The widest rupture sets how far the searches reach.
    assert_eq!(t.widest_rupture(), expect(60.0, 60.0).1);
    // A pair's own angle, both ways, for its pull and its rupture.
    let paired = "[[material_pairs]]\nmaterials = [\"a\", \"c\"]\ncontact_angle = 80\n";
    let t = table(&scene(paired)).unwrap();
    let own = expect(80.0, 80.0);
    assert_eq!((t.bridge(0, 2).tension, t.bridge(0, 2).rupture), own);
    assert_eq!((t.bridge(2, 0).tension, t.bridge(2, 0).rupture), own);
    assert_eq!(t.bridge(2, 2).tension, 0.05);
    // Refused without a liquid, and out of range (a material's and a pair's).
    let dry = "scene = \"freefall\"\nspheres = 20\n[[materials]]\nname = \"a\"\n\
               contact_angle = 10\n";
    let e = table(dry).unwrap_err().to_string();
    assert!(e.contains("applies to cohesion = \"capillary\""), "{e}");
    let dry_pair = "scene = \"freefall\"\nspheres = 20\n[[materials]]\nname = \"a\"\n\
                    [[material_pairs]]\nmaterials = [\"a\", \"a\"]\ncontact_angle = 10\n";
    let e = table(dry_pair).unwrap_err().to_string();
    assert!(e.contains("applies to cohesion = \"capillary\""), "{e}");
    let e = table(&scene("[[materials]]\nname = \"d\"\ncontact_angle = 95\n"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("\"d\"") && e.contains("90°"), "{e}");
    let steep = "[[material_pairs]]\nmaterials = [\"a\", \"b\"]\ncontact_angle = 90\n";
    let e = table(&scene(steep)).unwrap_err().to_string();
    assert!(e.contains("\"a\"–\"b\"") && e.contains("90°"), "{e}");
}

#[test]
fn clump_tables_make_the_generated_spheres_clumps_of_their_shapes() {
    let scene = |extra: &str| {
        format!("scene = \"freefall\"\nspheres = 400\nseed = 3\ndensity = 2000\n{extra}")
    };
    let build = |text: &str| {
        SceneConfig::parse(Some(text), None, &Overrides::default()).and_then(|c| c.build())
    };
    let spheres = build(&scene("")).unwrap().particles;
    let tables = "[[clump]]\nshape = \"tetrahedron\"\nfraction = 3\n\
                  [[clump]]\nname = \"bean\"\nspheres = [[0, 0, 0, 1], [1.2, 0, 0, 0.8]]\n";
    let start = build(&scene(tables)).unwrap();
    let p = &start.particles;
    let set = &p.clumps;
    assert_eq!(set.clumps.len(), 400);
    // Drawn by weight: about three tetrahedra to a bean.
    let tetrahedra = set
        .clumps
        .iter()
        .filter(|c| set.kinds[c.kind].template.name == "tetrahedron")
        .count();
    assert!((270..330).contains(&tetrahedra), "{tetrahedra} tetrahedra");
    assert_eq!(p.len(), 4 * tetrahedra + 2 * (400 - tetrahedra));
    for (k, c) in set.clumps.iter().enumerate() {
        // Each in the place of its sphere: its centre the sphere's, its bounding sphere the
        // sphere's, so no two clumps overlap (the spheres did not).
        let at = DVec3::from_array(spheres.exact_position(k));
        assert!((c.body.position - at).length() < 1e-12);
        let kind = &set.kinds[c.kind];
        let bound = kind
            .template
            .components
            .iter()
            .map(|t| t.centre.length() + t.radius)
            .fold(0.0, f64::max);
        assert!(
            (bound / spheres.radii[k] as f64 - 1.0).abs() < 1e-6,
            "bound {bound}"
        );
        // At the material's density.
        let volume = kind.inertia.mass / 2000.0;
        assert!(volume < 4.0 / 3.0 * std::f64::consts::PI * bound.powi(3));
    }
    // The same seed, the same clumps; turned at random.
    assert_eq!(build(&scene(tables)).unwrap().particles.clumps, *set);
    assert_ne!(
        set.clumps[0].body.orientation,
        set.clumps[1].body.orientation
    );
    // The resolved scene keeps its tables.
    let config = SceneConfig::parse(Some(&scene(tables)), None, &Overrides::default()).unwrap();
    let saved = toml::to_string(&config.resolved(&start)).unwrap();
    let again = SceneConfig::parse(Some(&saved), None, &Overrides::default()).unwrap();
    assert_eq!(again.build().unwrap().particles.clumps, *set);
}

#[test]
fn a_source_names_its_grains_by_particle_or_a_mixture_by_particles() {
    let build = |text: &str| {
        SceneConfig::parse(Some(text), None, &Overrides::default()).and_then(|c| c.build())
    };
    let clumps = |text: &str| build(text).unwrap().particles.clumps;
    let source = "scene = \"freefall\"\nspheres = 200\nseed = 3\n";
    let bean = "[[clump]]\nname = \"bean\"\nspheres = [[0, 0, 0, 1], [1.2, 0, 0, 0.8]]\n";
    // A built-in shape needs no table.
    let tetrahedra = clumps(&format!("{source}particle = \"tetrahedron\"\n"));
    let tables = format!("{source}[[clump]]\nshape = \"tetrahedron\"\n");
    assert_eq!(tetrahedra, clumps(&tables));
    // A mixture is the tables it names with its fractions, in its order; a table it does not
    // name is not drawn.
    let rod = "[[clump]]\nshape = \"rod\"\ncount = 3\n";
    let mixed = clumps(&format!(
        "[source]\n{source}particles = [{{ clump = \"bean\", fraction = 0.3 }}, \
         {{ clump = \"dimer\", fraction = 0.7 }}]\n{rod}{bean}"
    ));
    let weighted = clumps(&format!(
        "{source}{bean}fraction = 0.3\n[[clump]]\nshape = \"dimer\"\nfraction = 0.7\n"
    ));
    assert_eq!(mixed, weighted);
    let names: std::collections::HashSet<_> = mixed
        .kinds
        .iter()
        .map(|k| k.template.name.as_str())
        .collect();
    assert_eq!(names, ["bean", "dimer"].into_iter().collect());
    // A rod of three is named as its table makes it; its flat key is the source's.
    let rods = clumps(&format!("{source}particle = \"rod 3\"\n{rod}{bean}"));
    assert!(rods.kinds.iter().all(|k| k.template.components.len() == 3));
    // Refused, each with one error naming the key.
    for (extra, expect) in [
        (
            "particle = \"dimer\"\nparticles = [{ clump = \"dimer\" }]\n".to_string(),
            "give one",
        ),
        (
            format!("particle = \"pebble\"\n{bean}"),
            "\"pebble\": not one of the [[clump]] tables (\"bean\")",
        ),
        ("particle = \"pebble\"\n".into(), "no [[clump]] tables"),
        ("particle = 3\n".into(), "must be the name"),
        (
            format!("particles = [{{ clump = \"bean\", fraction = 1 }}]\n{bean}fraction = 2\n"),
            "in one place",
        ),
        (
            "particles = [{ clump = \"dimer\" }, { clump = \"dimer\" }]\n".into(),
            "twice",
        ),
        (
            "particles = [{ shape = \"dimer\" }]\n".into(),
            "takes entries",
        ),
        (
            "particles = [{ clump = \"dimer\", fraction = -1 }]\n".into(),
            "positive weight",
        ),
    ] {
        let e = build(&format!("{source}{extra}"))
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(expect), "{extra}: {e}");
    }
    let e = build("scene = \"input\"\ninput = \"clumps.csv\"\nparticle = \"dimer\"\n")
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("source.particles") && e.contains("file's rows"),
        "{e}"
    );
}

#[test]
fn a_clump_table_takes_its_spheres_from_a_file_and_may_give_its_density() {
    let dir = tempfile::tempdir().unwrap();
    // A bean's two spheres, as the `spheres` key of the test above gives them.
    std::fs::write(
        dir.path().join("bean.csv"),
        "x,y,z,r\n0,0,0,1\n1.2,0,0,0.8\n",
    )
    .unwrap();
    let scene = dir.path().join("scene.toml");
    let build = |table: &str| {
        let text = format!("scene = \"freefall\"\nspheres = 50\nseed = 3\n{table}");
        SceneConfig::parse(Some(&text), Some(&scene), &Overrides::default())
            .and_then(|c| c.build())
            .unwrap()
            .particles
            .clumps
    };
    let given = build("[[clump]]\nname = \"bean\"\nspheres = [[0, 0, 0, 1], [1.2, 0, 0, 0.8]]\n");
    // The file's stem names it; its spheres (read relative to the scene file; their radii
    // as a sphere file's, in f32) are the same.
    let read = build("[[clump]]\nfile = \"bean.csv\"\n");
    assert_eq!(read.clumps.len(), given.clumps.len());
    for (a, b) in read.kinds.iter().zip(&given.kinds) {
        assert_eq!(a.template.name, "bean");
        assert!((a.inertia.mass / b.inertia.mass - 1.0).abs() < 1e-6);
        assert!(
            (a.inertia.moments / b.inertia.moments - 1.0)
                .abs()
                .max_element()
                < 1e-6
        );
    }
    // Its own density scales every mass and moment.
    let dense = build("[[clump]]\nfile = \"bean.csv\"\ndensity = 4000\n");
    let default_density = 500.0;
    for (a, b) in dense.kinds.iter().zip(&read.kinds) {
        let ratio = a.inertia.mass / b.inertia.mass;
        assert!((ratio - 4000.0 / default_density).abs() < 1e-9, "{ratio}");
        assert!(
            (a.inertia.moments / b.inertia.moments - ratio)
                .abs()
                .max_element()
                < 1e-9
        );
    }
}

#[test]
fn bad_clump_tables_are_one_clear_error() {
    let build = |text: &str| {
        SceneConfig::parse(Some(text), None, &Overrides::default())
            .and_then(|c| c.build())
            .map(|_| ())
            .unwrap_err()
            .to_string()
    };
    let freefall = "scene = \"freefall\"\nspheres = 20\n";
    for (table, expect) in [
        ("[[clump]]\nfraction = 1\n", "needs a shape"),
        ("[[clump]]\nshape = \"cube\"\n", "not one of dimer"),
        (
            "[[clump]]\nshape = \"dimer\"\nspheres = [[0, 0, 0, 1]]\n",
            "give one",
        ),
        (
            "[[clump]]\nshape = \"dimer\"\ncount = 3\n",
            "count is the spheres",
        ),
        ("[[clump]]\nshape = \"rod\"\ncount = 0\n", "count ≥ 1"),
        (
            "[[clump]]\nshape = \"dimer\"\nfraction = 0\n",
            "positive weight",
        ),
        ("[[clump]]\nspheres = [[0, 0, 0, -1]]\n", "positive radius"),
        ("[[clump]]\nspheres = []\n", "no component"),
        (
            "[[clump]]\nshape = \"dimer\"\nfile = \"grain.csv\"\n",
            "give one",
        ),
        (
            "[[clump]]\nshape = \"dimer\"\ndensity = -2\n",
            "positive density",
        ),
        (
            "[[clump]]\nshape = \"dimer\"\ndensity = 2\nmass = 1\n",
            "give one",
        ),
        ("[[clump]]\nshape = \"dimer\"\nmass = 0\n", "positive mass"),
        (
            "[[clump]]\nshape = \"dimer\"\ninertia = [1, 1, 1]\n",
            "give mass",
        ),
        (
            "[[clump]]\nshape = \"dimer\"\nmass = 1\ninertia = [1, 1]\n",
            "got 2 values",
        ),
        (
            "[[clump]]\nshape = \"dimer\"\nmass = 1\ninertia = [1, 1, 3]\n",
            "not a rigid body's",
        ),
        (
            "[[clump]]\nshape = \"dimer\"\nmass = 1\ninertia = [1, 1, 1, 2, 0, 0]\n",
            "not a rigid body's",
        ),
        (
            "[[clump]]\nshape = \"dimer\"\nmaterial = \"steel\"\n",
            "no [[materials]] tables",
        ),
    ] {
        let e = build(&format!("{freefall}{table}"));
        assert!(e.contains("clump") && e.contains(expect), "{table}: {e}");
    }
    let agglomerate = "scene = \"agglomerate\"\n[[clump]]\nshape = \"dimer\"\n";
    let e = build(agglomerate);
    assert!(e.contains("not of scene \"agglomerate\"'s yet"), "{e}");
}

#[test]
fn a_clump_table_may_take_its_shape_from_a_mesh_beside_the_scene() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let origin = data.join("scene.toml");
    let text =
        "scene = \"freefall\"\nspheres = 12\n[[clump]]\nmesh = \"box.obj\"\nspacing = 0.25\n";
    let config = SceneConfig::parse(Some(text), Some(&origin), &Overrides::default()).unwrap();
    assert!(config.files().any(|f| f == data.join("box.obj")));
    let set = config.build().unwrap().particles.clumps;
    assert_eq!(set.clumps.len(), 12);
    // The box (1.75 × 2 × 0.75) filled at a spacing of 0.25: 7 × 8 × 3 touching spheres.
    let kind = &set.kinds[set.clumps[0].kind];
    assert_eq!(kind.template.name, "box");
    assert_eq!(kind.template.components.len(), 7 * 8 * 3);
    let bad = |table: &str| {
        SceneConfig::parse(
            Some(&format!(
                "scene = \"freefall\"\nspheres = 12\n[[clump]]\n{table}"
            )),
            Some(&origin),
            &Overrides::default(),
        )
        .and_then(|c| c.build())
        .map(|_| ())
        .unwrap_err()
        .to_string()
    };
    let e = bad("shape = \"dimer\"\nmesh = \"box.obj\"\n");
    assert!(
        e.contains("more than one of shape, spheres, mesh and file"),
        "{e}"
    );
    let e = bad("shape = \"dimer\"\nspacing = 0.1\n");
    assert!(e.contains("spacing is the fill's of a mesh"), "{e}");
    let e = bad("mesh = \"nowhere.obj\"\n");
    assert!(e.contains("nowhere.obj"), "{e}");
}

#[test]
fn the_gravel_scene_is_the_drum_turning_clumps_of_its_mix() {
    let build = |text: &str| {
        SceneConfig::parse(Some(text), None, &Overrides::default())
            .and_then(|c| c.build())
            .unwrap()
    };
    let gravel = build("scene = \"gravel\"\nspheres = 300\nseed = 4\n");
    let set = &gravel.particles.clumps;
    assert_eq!(set.clumps.len(), 300);
    let mut names: Vec<&str> = set.kinds.iter().map(|k| k.template.name.as_str()).collect();
    names.sort();
    names.dedup();
    assert_eq!(names, ["rod 3", "tetrahedron", "trimer"]);
    // The drum's walls, box and grains, as the drum with the same tables.
    let drum = build(
        "scene = \"drum\"\nspheres = 300\nseed = 4\n\
         [[clump]]\nshape = \"tetrahedron\"\nfraction = 0.4\n\
         [[clump]]\nshape = \"trimer\"\nfraction = 0.3\n\
         [[clump]]\nshape = \"rod\"\ncount = 3\nfraction = 0.3\n",
    );
    assert_eq!(drum.particles.clumps, *set);
    assert_eq!(drum.params.box_hi, gravel.params.box_hi);
    assert_eq!(drum.walls.meshes.len(), gravel.walls.meshes.len());
    // Tables of its own replace the mix.
    let own = build("scene = \"gravel\"\nspheres = 50\n[[clump]]\nshape = \"dimer\"\n");
    assert!(
        own.particles
            .clumps
            .kinds
            .iter()
            .all(|k| k.template.name == "dimer")
    );
}
