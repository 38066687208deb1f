//! A poured pile stepped on the ranks of `mpirun` (the `mpi` feature): the box cut into slabs
//! along its longest axis, each rank stepping the spheres of its slab with the cpu backend.
//! Rank 0 prints each rank's spheres, ghosts and time, gathers the run, and with `--check`
//! steps the whole run alone and says whether the two agree bit for bit (exit status 1 where
//! they do not).
//!
//! ```sh
//! cargo build --release --features mpi --example mpi_pour
//! mpirun -np 4 target/release/examples/mpi_pour [SPHERES] [STEPS] [--check]
//! ```

use mochi::dem::Stepper;
use mochi::dem::scene::{Overrides, SceneConfig};
use mochi::distributed::{Comm, MpiComm, RankStepper};
use mochi::engines::DemSetup;
use mochi::engines::cpu::CpuStepper;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let check = args.iter().any(|a| a == "--check");
    let mut numbers = args.iter().filter(|a| !a.starts_with("--"));
    let spheres: usize = numbers.next().map_or(Ok(2000), |a| a.parse())?;
    let steps: u32 = numbers.next().map_or(Ok(2000), |a| a.parse())?;

    let comm = MpiComm::world()?;
    let scene = format!("scene = \"pour\"\nspheres = {spheres}\nseed = 7\n");
    let start = SceneConfig::parse(Some(&scene), None, &Overrides::default())?.build()?;
    let setup = DemSetup {
        particles: start.particles,
        params: start.params,
        mode: start.mode,
        walls: start.walls,
    };
    let mut rank = RankStepper::new(comm, &setup)?;
    let began = Instant::now();
    let decomposed_contacts = rank.advance(steps)?.contacts;
    let ms = began.elapsed().as_secs_f64() * 1e3 / steps.max(1) as f64;

    // Each rank's share, to rank 0.
    let comm = rank.comm();
    let share = [rank.own_spheres() as f64, rank.ghost_spheres() as f64, ms];
    let mut outgoing = vec![Vec::new(); comm.size()];
    outgoing[0] = share.iter().flat_map(|x| x.to_le_bytes()).collect();
    let shares = comm.exchange(outgoing)?;
    let whole = rank.gather()?;
    let Some(decomposed) = whole else {
        return Ok(());
    };
    for (r, bytes) in shares.iter().enumerate() {
        let x: Vec<f64> = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        println!(
            "rank {r}: {} spheres, {} ghosts, {:.3} ms a step",
            x[0], x[1], x[2]
        );
    }
    if !check {
        return Ok(());
    }
    let mut alone = CpuStepper::open(setup)?;
    let contacts = alone.advance(steps)?.contacts;
    let expected = alone.particles()?;
    let differ = (0..expected.len()).find(|&i| {
        let bits = |p: &mochi::dem::Particles| {
            let x = p.exact_position(i).map(f64::to_bits);
            (
                x,
                p.velocities[i].map(f32::to_bits),
                p.angular_velocities[i].map(f32::to_bits),
            )
        };
        bits(&decomposed) != bits(&expected) || decomposed.history.of(i) != expected.history.of(i)
    });
    if decomposed_contacts != contacts {
        eprintln!("{decomposed_contacts} contacts, where the whole run has {contacts}");
        std::process::exit(1);
    }
    match differ {
        None => {
            println!(
                "the {} ranks' run is the whole run bit for bit ({} spheres, {contacts} contacts, {steps} steps)",
                shares.len(),
                expected.len()
            );
            Ok(())
        }
        Some(i) => {
            eprintln!("sphere {i} differs from the whole run's");
            std::process::exit(1);
        }
    }
}
