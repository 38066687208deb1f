//! Positions that never freeze (docs/method.md, "Positions that never freeze"): a
//! slow sphere far from the origin moves by every step's displacement on every backend, in the
//! paper's kernels and the granular ones, though each is far below the spacing of `f32` at its
//! centre; frames hold the positions with the digits to tell, and a run resumed from its
//! checkpoint goes on bit for bit.
//!
//! The flight: spheres of 1 mm at 1, 10 and 100 m from the origin (each coordinate that far,
//! either sign) at 1 mm/s along each axis, 10⁴ steps of 1e-7 s: 1 µm along each axis. `f32`
//! alone rounds each step's 1e-10 m to 0 at 1 m and beyond (its spacing there is 1.2e-7 m, at
//! 100 m 7.6e-6 m), so a step that loses the displacement moves nothing, and one that rounds it
//! up moves whole spacings: both fail here.

mod common;

use common::on_every_backend;
use mochi::dem::model::{ContactLaw, Material};
use mochi::dem::{Particles, StepParams, Stepper};
use mochi::engines::wgpu::compute::GridBuild;
use mochi::engines::{BackendKind, Options, open_stepper};
use mochi::io::{Frame, read_checkpoint, read_frame, read_particles, write_checkpoint};
use mochi::proxy::ProxyMode;

const STEPS: u32 = 10_000;
const DT: f64 = 1e-7;
/// Along each axis \[m/s\].
const SPEED: f32 = 1e-3;
const RADIUS: f32 = 5e-4;
/// Half the side of the box \[m\]: its walls lie 100 m beyond the farthest sphere.
const HALF_BOX: f64 = 200.0;
/// Each sphere's distance from the origin along each axis \[m\], and how close to 1 µm its
/// displacement must come (relative): at 100 m the residual's own rounding is 8 times coarser
/// than at 10 m.
const FLIGHTS: [(f32, f64); 3] = [(1.0, 1e-3), (10.0, 1e-3), (100.0, 1e-2)];

/// The expected displacement along each axis \[m\].
fn flight() -> f64 {
    STEPS as f64 * DT * SPEED as f64
}

/// Two spheres at each distance of [`FLIGHTS`], one with every coordinate positive and one
/// with every coordinate negative, each moving away from the origin on one axis and towards it
/// on the others (1 m of a sphere's flight is 5·10⁵ radii from the next: no contacts).
fn slow_spheres() -> Particles {
    let mut p = Particles::default();
    for (d, _) in FLIGHTS {
        for sign in [1.0f32, -1.0] {
            p.positions.push([sign * d, sign * d * 0.7, sign * d * 1.3]);
            p.velocities.push([SPEED, -SPEED, SPEED].map(|v| sign * v));
            p.angular_velocities.push([0.0; 3]);
            p.radii.push(RADIUS);
        }
    }
    p
}

/// The paper's law (its kernels on the GPUs) or Hertz–Mindlin at glass's stiffness with
/// friction and rolling resistance (the granular kernels), in the box ±[`HALF_BOX`], without
/// gravity.
fn params(granular: bool) -> StepParams {
    let material = match granular {
        false => Material::default(),
        true => Material {
            density: 2500.0,
            contact: ContactLaw::HertzMindlin {
                young_modulus: 6.3e10,
                poisson_ratio: 0.2,
            },
            friction: 0.5,
            rolling_friction: 0.1,
            ..Material::default()
        },
    };
    let (lo, hi) = ([-HALF_BOX; 3], [HALF_BOX; 3]);
    StepParams::new(&material, DT, lo, hi, [0.0; 3], 0.0, RADIUS).unwrap()
}

fn stepper(
    kind: BackendKind,
    start: &Particles,
    p: StepParams,
    options: &Options,
) -> Box<dyn Stepper> {
    open_stepper(kind, start.clone(), p, ProxyMode::Mochi, options)
        .unwrap_or_else(|e| panic!("{} opens: {e}", kind.name()))
}

/// Asserts that each sphere of `end` (as positions, `f64`) moved from its place in `start` by
/// its velocity's [`flight`] along each axis, to within its distance's tolerance.
fn assert_flew(what: &str, start: &[[f64; 3]], end: &[[f64; 3]], velocities: &[[f32; 3]]) {
    assert_eq!(start.len(), end.len(), "{what}");
    for (i, ((a, b), v)) in start.iter().zip(end).zip(velocities).enumerate() {
        let tolerance = FLIGHTS[i / 2].1;
        for k in 0..3 {
            let moved = b[k] - a[k];
            let expected = flight() * v[k].signum() as f64;
            let off = (moved / expected - 1.0).abs();
            assert!(
                off <= tolerance,
                "{what}: sphere {i} at {:?} moved {moved:e} m along axis {k}, expected \
                 {expected:e} m ({off:.2e} off, at most {tolerance:e})",
                a
            );
        }
    }
}

/// Exact positions of `p`.
fn exact(p: &Particles) -> Vec<[f64; 3]> {
    p.exact_positions().unwrap()
}

#[test]
fn slow_spheres_far_from_the_origin_move_by_every_step() {
    let start = slow_spheres();
    let from = exact(&start);
    on_every_backend(|kind| {
        for granular in [false, true] {
            let mut builds = vec![GridBuild::Auto];
            if kind == BackendKind::WgpuCompute {
                // The dense build too (its paper step skips binnings within a skin, and copies
                // the sorted state back when it bins).
                builds.push(GridBuild::Dense);
            }
            for grid_build in builds {
                let options = Options {
                    grid_build,
                    ..Options::default()
                };
                let mut s = stepper(kind, &start, params(granular), &options);
                s.advance(STEPS).unwrap();
                let end = s.particles().unwrap();
                assert_eq!(end.step, STEPS as u64);
                let what = format!(
                    "{} ({}, {grid_build:?} build)",
                    kind.name(),
                    ["paper's law", "granular"][granular as usize]
                );
                assert_flew(&what, &from, &exact(&end), &start.velocities);
                // The state is valid: every centre is its position rounded to f32.
                end.validate().unwrap();
            }
        }
    });
}

#[test]
fn frames_hold_the_positions_with_the_digits_to_tell() {
    // The flight's start and end frames in every format, read back: the displacement is in the
    // files (f32 coordinates could not tell 1 µm at 100 m), and a frame read as a run's start
    // (`--input`) puts each sphere where the run had it.
    let start = slow_spheres();
    let mut s = stepper(BackendKind::Cpu, &start, params(false), &Options::default());
    let first = s.particles().unwrap();
    s.advance(STEPS).unwrap();
    let end = s.particles().unwrap();
    assert!(end.position_residuals.iter().any(|r| *r != [0.0; 3]));
    let dir = tempfile::tempdir().unwrap();
    for ext in ["vtu", "csv", "npy"] {
        let read = |p: &Particles, name: &str| {
            let path = dir.path().join(format!("{name}.{ext}"));
            mochi::io::write_frame(&path, &Frame::of(p, DT as f32, None)).unwrap();
            (read_frame(&path).unwrap(), path)
        };
        let (a, _) = read(&first, "start");
        let (b, path) = read(&end, "end");
        assert_flew(
            ext,
            &a.exact_positions,
            &b.exact_positions,
            &start.velocities,
        );
        // As written: each position is the run's, its centre the run's centre.
        assert_eq!(b.exact_positions, exact(&end), "{ext}");
        assert_eq!(b.positions, end.positions, "{ext}");
        if ext != "vtu" {
            // A run started from the frame: the same centres, residuals to within f64's
            // rounding of their sums.
            let again = read_particles(&path).unwrap();
            assert_eq!(again.positions, end.positions, "{ext}");
            for (i, (x, y)) in exact(&again).iter().zip(exact(&end)).enumerate() {
                for k in 0..3 {
                    assert!(
                        (x[k] - y[k]).abs() <= y[k].abs() * 2f64.powi(-52),
                        "{ext}: {i}"
                    );
                }
            }
        }
    }
}

#[test]
fn a_run_resumed_from_its_checkpoint_flies_on_bit_for_bit() {
    // A tenth of the flight in two halves, a checkpoint written and read between them: the
    // same centres and residuals as the whole tenth at once (each sphere's integration alone
    // acts, so every backend's run is deterministic here, not the cpu's alone).
    let steps = STEPS / 10;
    let start = slow_spheres();
    let dir = tempfile::tempdir().unwrap();
    on_every_backend(|kind| {
        for granular in [false, true] {
            let p = params(granular);
            let mut whole = stepper(kind, &start, p.clone(), &Options::default());
            whole.advance(steps).unwrap();
            let whole = whole.particles().unwrap();
            assert!(whole.position_residuals.iter().any(|r| *r != [0.0; 3]));
            let mut first = stepper(kind, &start, p.clone(), &Options::default());
            first.advance(steps / 2).unwrap();
            let path = dir.path().join("checkpoint.bin");
            write_checkpoint(&path, &first.particles().unwrap(), "", "").unwrap();
            let halfway = read_checkpoint(&path).unwrap().particles;
            let mut second = stepper(kind, &halfway, p, &Options::default());
            second.advance(steps / 2).unwrap();
            let resumed = second.particles().unwrap();
            let bits = |p: &Particles| -> Vec<u32> {
                let lo = &p.position_residuals;
                p.positions
                    .iter()
                    .chain(lo)
                    .flatten()
                    .map(|x| x.to_bits())
                    .collect()
            };
            assert_eq!(resumed.step, whole.step);
            assert_eq!(
                bits(&resumed),
                bits(&whole),
                "{} ({})",
                kind.name(),
                ["paper's law", "granular"][granular as usize]
            );
        }
    });
}
