//! Fills a mesh (by default the Stanford bunny of the paper's bunny scene) with spheres of
//! radius r = 0.005 or r/2 on a jittered lattice of spacing 2.2·r, fitted into cubes of several
//! sides, and prints the time of each step and the sphere counts; then finds the side that gives
//! the paper's 82,337 spheres.
//!
//! ```sh
//! cargo run --release --example mesh_fill [-- MESH [SIDE...]]
//! ```

use mochi::mesh::{FillSpec, WindingTree, fill, load, winding_number};
use rand::{RngExt, SeedableRng};
use std::path::PathBuf;
use std::time::Instant;

const PAPER_COUNT: usize = 82_337;
const R: f32 = 0.005;

fn main() -> mochi::Result<()> {
    let mut args = std::env::args().skip(1);
    let path = args.next().map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/stanford-bunny.obj")
    });
    let sides: Vec<f64> = args.filter_map(|a| a.parse().ok()).collect();
    let sides = if sides.is_empty() {
        vec![0.3, 0.4, 0.5]
    } else {
        sides
    };

    let t = Instant::now();
    let mesh = load(&path)?;
    println!(
        "{}: {} vertices, {} triangles, loaded in {:.3} s; {} threads",
        path.display(),
        mesh.vertices.len(),
        mesh.triangles.len(),
        t.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    let spec = FillSpec {
        spacing: 2.2 * f64::from(R),
        radii: vec![(R, 1.0), (R / 2.0, 1.0)],
        jitter: true,
        seed: 1,
    };
    let run = |side: f64| -> mochi::Result<usize> {
        let fitted = mesh.fitted([0.0; 3], [side; 3]);
        let t = Instant::now();
        let (centers, _) = fill(&fitted, &spec)?;
        let (lo, hi) = fitted.bounds().unwrap_or_default();
        let lattice: f64 = (0..3)
            .map(|a| ((hi[a] - lo[a]) / spec.spacing).ceil())
            .product();
        println!(
            "side {side:.4}: {:>7} spheres of {lattice:.0} lattice points, filled in {:.3} s",
            centers.len(),
            t.elapsed().as_secs_f64()
        );
        Ok(centers.len())
    };
    let mut count = 0;
    for &side in &sides {
        count = run(side)?;
    }
    // The count grows as side³: a few steps of side ← side·(target/count)^⅓ find the paper's.
    let mut side = sides[sides.len() - 1];
    for _ in 0..5 {
        if count == PAPER_COUNT {
            break;
        }
        side *= (PAPER_COUNT as f64 / count.max(1) as f64).cbrt();
        count = run(side)?;
    }
    let (lo, hi) = mesh
        .fitted([0.0; 3], [side; 3])
        .bounds()
        .unwrap_or_default();
    println!(
        "closest to the paper's {PAPER_COUNT}: side {side:.4} (side/spacing {:.2}; the bunny \
         then measures {:.3} × {:.3} × {:.3}) gives {count}",
        side / spec.spacing,
        hi[0] - lo[0],
        hi[1] - lo[1],
        hi[2] - lo[2]
    );

    // How far the tree's winding number is from the exact one, on random points of the box.
    let fitted = mesh.fitted([0.0; 3], [side; 3]);
    let tree = WindingTree::new(&fitted);
    let (lo, hi) = fitted.bounds().unwrap_or_default();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    let (mut worst, mut sum, mut flips, n) = (0.0f64, 0.0, 0, 500);
    for _ in 0..n {
        let p: [f64; 3] = std::array::from_fn(|a| rng.random_range(lo[a]..hi[a]));
        let (fast, exact) = (tree.winding_number(p), winding_number(&fitted, p));
        worst = worst.max((fast - exact).abs());
        sum += (fast - exact).abs();
        flips += usize::from((fast >= 0.5) != (exact >= 0.5));
    }
    println!(
        "tree vs exact winding number on {n} random points: largest error {worst:.4}, mean \
         {:.5}, {flips} decided differently",
        sum / f64::from(n)
    );
    Ok(())
}
