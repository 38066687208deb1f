//! Beverloo's law on the built-in flat-bottomed hopper (issue 19; physics.md, "Analytic
//! results"): W = C·ρ_b·√g·(D − k·d)^{5/2}. Drains the `hopper` scene on the cpu backend (the
//! one that runs outflows) at several orifice diameters D, with spheres in proportion to D³
//! (the hopper is 5·D wide: the fill then stands as many orifices high at every D), and the
//! middle one again with twice the spheres (a fill about twice as high); measures each steady mass flow rate W over
//! [`WINDOW`] after the gate has been open [`SETTLING`] (`dem::equipment::mass_flow_rate`: the
//! slope of the mass out between 20 % and 80 % of what left in the window; the flow is steady
//! while the fill stands well above the orifice) and the bulk density ρ_b of the fill when the
//! gate opens; fits C and k by least squares of
//! W^{2/5} against D, and compares the two fill heights.
//!
//! ```sh
//! cargo run --release --example beverloo [-- [--settle S] [--window W] [--seed N] [--one-fill]
//!     SPHERES [D/d ...]]
//! ```
//! (defaults: settle 0.1 s, window 0.4 s, the scene's seed, 1500 spheres at the smallest D,
//! D/d = 4, 5, 6 with d the mean diameter, 8 mm; `--one-fill` leaves out the taller fill, so
//! that runs of several seeds and fills can go side by side).

use mochi::dem::equipment::mass_flow_rate;
use mochi::dem::model::mass;
use mochi::dem::scene::{Overrides, SceneConfig};
use mochi::engines::{BackendChoice, BackendKind, Options, open_scene};
use std::time::Instant;

/// Mean sphere radius of the built-in hopper \[m\].
const GRAIN_RADIUS: f64 = 0.004;
/// The gate opens at this time \[s\] (the scene's default).
const OPEN: f64 = 0.2;
/// The flow is measured by default from this long after the gate opens \[s\], over
/// [`WINDOW`] \[s\].
const SETTLING: f64 = 0.1;
const WINDOW: f64 = 0.4;
/// Steps between two samples of the mass out.
const SAMPLE: u32 = 200;

/// What one drain measured.
struct Drain {
    orifice: f64,
    spheres: usize,
    /// Bulk density of the fill at the gate's opening \[kg/m³\].
    bulk: f64,
    /// Steady mass flow rate \[kg/s\].
    rate: f64,
    seconds: f64,
}

/// How the drains run.
struct Plan {
    /// From the gate's opening to the window's start \[s\].
    settle: f64,
    /// The window's length \[s\].
    window: f64,
    /// The scene's seed (its default where `None`).
    seed: Option<u64>,
    /// Whether the middle orifice is drained again with twice the spheres.
    taller: bool,
}

fn drain(orifice: f64, spheres: usize, plan: &Plan) -> mochi::Result<Drain> {
    let clock = Instant::now();
    let mut overrides = vec![
        "scene=hopper".to_owned(),
        format!("spheres={spheres}"),
        format!("hopper_orifice={orifice}"),
        format!("hopper_open={OPEN}"),
        "frame_every=0".to_owned(),
    ];
    overrides.extend(plan.seed.map(|s| format!("seed={s}")));
    let start = SceneConfig::load(None, &Overrides::parse(&overrides)?)?.build()?;
    let (dt, density) = (start.params.dt as f64, start.params.density);
    let cylinder = 2.5 * orifice;
    let mut stepper = open_scene(
        BackendChoice::Named(BackendKind::Cpu),
        start,
        &Options::default(),
    )?
    .value;
    let mut samples = Vec::new();
    let mut bulk = None;
    let mut t = 0.0;
    let (from, to) = (OPEN + plan.settle, OPEN + plan.settle + plan.window);
    while t < to {
        stepper.advance(SAMPLE)?;
        t += SAMPLE as f64 * dt;
        if bulk.is_none() && t >= OPEN {
            bulk = Some(bulk_density(&stepper.particles()?, density, cylinder));
        }
        if t >= from {
            let out = stepper.flow_counts().map_or(0.0, |c| c.removed_mass);
            samples.push((t, out));
        }
    }
    // The mass out since the window began.
    let first = samples.first().map_or(0.0, |s| s.1);
    let samples: Vec<(f64, f64)> = samples.iter().map(|&(t, m)| (t, m - first)).collect();
    Ok(Drain {
        orifice,
        spheres,
        bulk: bulk.unwrap_or(f64::NAN),
        rate: mass_flow_rate(&samples).unwrap_or(f64::NAN),
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// The mass per volume of the spheres whose centres lie in the hopper's cylinder of radius
/// `cylinder`, between two diameters above the floor and two below the fill's top.
fn bulk_density(p: &mochi::dem::Particles, density: f32, cylinder: f64) -> f64 {
    let d = 2.0 * GRAIN_RADIUS;
    let top = p
        .positions
        .iter()
        .zip(&p.radii)
        .map(|(c, &r)| (c[2] + r) as f64)
        .fold(f64::MIN, f64::max);
    let (lo, hi) = (2.0 * d, top - 2.0 * d);
    let inside: f64 = p
        .positions
        .iter()
        .zip(&p.radii)
        .filter(|(c, _)| (lo..hi).contains(&(c[2] as f64)))
        .map(|(_, &r)| mass(density, r) as f64)
        .sum();
    inside / (std::f64::consts::PI * cylinder * cylinder * (hi - lo))
}

/// Least-squares line y = a·x + b through `points`.
fn line(points: &[(f64, f64)]) -> (f64, f64) {
    let n = points.len() as f64;
    let (sx, sy) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), &(x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), &(x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    let a = sxy / sxx;
    (a, my - a * mx)
}

fn main() -> mochi::Result<()> {
    let mut args = std::env::args().skip(1).peekable();
    let mut plan = Plan {
        settle: SETTLING,
        window: WINDOW,
        seed: None,
        taller: true,
    };
    let usage = || -> ! {
        eprintln!(
            "usage: beverloo [--settle S] [--window W] [--seed N] [--one-fill] [SPHERES [D/d ...]]"
        );
        std::process::exit(2)
    };
    while let Some(flag) = args.next_if(|a| a.starts_with("--")) {
        if flag == "--one-fill" {
            plan.taller = false;
            continue;
        }
        let value = args.next().unwrap_or_else(|| usage());
        match flag.as_str() {
            "--settle" => plan.settle = value.parse().unwrap_or_else(|_| usage()),
            "--window" => plan.window = value.parse().unwrap_or_else(|_| usage()),
            "--seed" => plan.seed = Some(value.parse().unwrap_or_else(|_| usage())),
            _ => usage(),
        }
    }
    let spheres: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(1500);
    let ratios: Vec<f64> = args.filter_map(|a| a.parse().ok()).collect();
    let ratios = if ratios.is_empty() {
        vec![4.0, 5.0, 6.0]
    } else {
        ratios
    };
    let d = 2.0 * GRAIN_RADIUS;
    println!("| D [m] | D/d | spheres | ρ_b [kg/m³] | W [kg/s] | run [s] |");
    println!("| --- | --- | --- | --- | --- | --- |");
    let show = |r: &Drain| {
        println!(
            "| {:.3} | {:.1} | {} | {:.0} | {:.4e} | {:.0} |",
            r.orifice,
            r.orifice / d,
            r.spheres,
            r.bulk,
            r.rate,
            r.seconds
        )
    };
    let smallest = ratios.iter().copied().fold(f64::MAX, f64::min);
    let spheres_at = |ratio: f64| (spheres as f64 * (ratio / smallest).powi(3)).round() as usize;
    let mut drains = Vec::new();
    for &ratio in &ratios {
        let r = drain(ratio * d, spheres_at(ratio), &plan)?;
        show(&r);
        drains.push(r);
    }
    let middle_ratio = ratios[ratios.len() / 2];
    let middle = middle_ratio * d;
    let taller = if plan.taller {
        let taller = drain(middle, 2 * spheres_at(middle_ratio), &plan)?;
        show(&taller);
        Some(taller)
    } else {
        None
    };
    let g: f64 = 9.81;
    let bulk = drains.iter().map(|r| r.bulk).sum::<f64>() / drains.len() as f64;
    let points: Vec<(f64, f64)> = drains
        .iter()
        .map(|r| (r.orifice, r.rate.powf(0.4)))
        .collect();
    if points.len() < 2 {
        println!("\n(the fit to Beverloo's law needs two orifices or more)");
    } else {
        let (a, b) = line(&points);
        let k = -b / (a * d);
        let c = a.powf(2.5) / (bulk * g.sqrt());
        println!(
            "\nfit W^(2/5) = a·(D − k·d): C = {c:.3}, k = {k:.2} (ρ_b {bulk:.0} kg/m³; Beverloo: \
             C ≈ 0.58, k ≈ 1.4–1.5)"
        );
    }
    let Some(taller) = taller else {
        return Ok(());
    };
    let same = drains
        .iter()
        .find(|r| r.orifice == middle)
        .expect("the middle orifice was drained");
    println!(
        "fill height: W = {:.4e} kg/s with {} spheres, {:.4e} with {} ({:+.1} %)",
        same.rate,
        same.spheres,
        taller.rate,
        taller.spheres,
        100.0 * (taller.rate / same.rate - 1.0)
    );
    Ok(())
}
