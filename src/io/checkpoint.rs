//! Checkpoints: the particles, the step count and the scene (as TOML) in one little-endian
//! binary file, written atomically so the file on disk is always a whole checkpoint.
//!
//! Layout: `MOCHICKP`, version u32 (1), step u64, n u64, scene length u64, scene TOML (UTF-8),
//! then n·3 f32 positions, n·3 f32 velocities, n f32 radii.

use super::{io_error, write_atomically};
use crate::dem::Particles;
use crate::error::{Error, Result};
use std::path::Path;

const MAGIC: &[u8; 8] = b"MOCHICKP";
const VERSION: u32 = 1;

/// Writes `particles` and `scene` (TOML) to `path`, atomically.
pub fn write_checkpoint(path: &Path, particles: &Particles, scene: &str) -> Result<()> {
    write_atomically(path, |out| {
        out.write_all(MAGIC)?;
        out.write_all(&VERSION.to_le_bytes())?;
        out.write_all(&particles.step.to_le_bytes())?;
        out.write_all(&(particles.len() as u64).to_le_bytes())?;
        out.write_all(&(scene.len() as u64).to_le_bytes())?;
        out.write_all(scene.as_bytes())?;
        let floats = particles
            .positions
            .iter()
            .flatten()
            .chain(particles.velocities.iter().flatten())
            .chain(&particles.radii);
        let bytes: Vec<u8> = floats.flat_map(|x| x.to_le_bytes()).collect();
        out.write_all(&bytes)
    })
}

/// Reads a checkpoint: the particles and the scene TOML it was saved with.
pub fn read_checkpoint(path: &Path) -> Result<(Particles, String)> {
    let bytes = std::fs::read(path).map_err(io_error(path))?;
    let bad = |msg: String| Error::Parse {
        path: path.to_owned(),
        line: None,
        msg,
    };
    let mut at = 0usize;
    let mut take = |len: usize, what: &str| -> Result<&[u8]> {
        let end = at
            .checked_add(len)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| bad(format!("truncated checkpoint: {what} missing")))?;
        let s = &bytes[at..end];
        at = end;
        Ok(s)
    };
    if take(8, "header")? != MAGIC {
        return Err(bad("not a mochi checkpoint".into()));
    }
    let u64_at = |s: &[u8]| u64::from_le_bytes(s.try_into().expect("8 bytes"));
    let version = u32::from_le_bytes(take(4, "version")?.try_into().expect("4 bytes"));
    if version != VERSION {
        return Err(bad(format!(
            "checkpoint version {version}; this mochi reads version {VERSION}"
        )));
    }
    let step = u64_at(take(8, "step")?);
    let n = u64_at(take(8, "sphere count")?);
    let scene_len = u64_at(take(8, "scene length")?);
    let scene = take(scene_len.try_into().unwrap_or(usize::MAX), "scene")?;
    let scene = std::str::from_utf8(scene)
        .map_err(|_| bad("the scene is not UTF-8".into()))?
        .to_owned();
    let floats = n
        .checked_mul(7 * 4)
        .and_then(|b| usize::try_from(b).ok())
        .ok_or_else(|| bad(format!("{n} spheres cannot fit in memory")))?;
    let data = take(floats, "sphere data")?;
    if at != bytes.len() {
        return Err(bad(format!(
            "{} unexpected bytes at the end",
            bytes.len() - at
        )));
    }
    let values: Vec<f32> = data
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    let n = n as usize;
    let triples = |s: &[f32]| s.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let particles = Particles {
        positions: triples(&values[..3 * n]),
        velocities: triples(&values[3 * n..6 * n]),
        radii: values[6 * n..].to_vec(),
        step,
    };
    particles.validate().map_err(|e| bad(e.to_string()))?;
    if let Some(i) = particles
        .radii
        .iter()
        .position(|&r| !(r > 0.0 && r.is_finite()))
    {
        return Err(bad(format!("sphere {i} has radius {}", particles.radii[i])));
    }
    Ok((particles, scene))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Particles {
        Particles {
            positions: vec![[0.1, 0.2, 0.3], [1.0, -2.0, 3.5]],
            velocities: vec![[0.0, -1.5, 2.0], [1e-9, 0.0, -0.0]],
            radii: vec![0.01, 0.002],
            step: 1234,
        }
    }

    #[test]
    fn a_checkpoint_round_trips_bit_for_bit() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        write_checkpoint(&path, &sample(), "scene = \"slab\"\n").unwrap();
        let (p, scene) = read_checkpoint(&path).unwrap();
        assert_eq!(p, sample());
        assert_eq!(scene, "scene = \"slab\"\n");
    }

    #[test]
    fn damaged_checkpoints_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.bin");
        write_checkpoint(&path, &sample(), "x").unwrap();
        let whole = std::fs::read(&path).unwrap();
        for cut in [0, 5, 20, whole.len() - 1] {
            std::fs::write(&path, &whole[..cut]).unwrap();
            let e = read_checkpoint(&path).unwrap_err().to_string();
            assert!(
                e.contains("truncated") || e.contains("not a mochi"),
                "{cut}: {e}"
            );
        }
        let mut extra = whole.clone();
        extra.push(0);
        std::fs::write(&path, &extra).unwrap();
        assert!(
            read_checkpoint(&path)
                .unwrap_err()
                .to_string()
                .contains("unexpected")
        );
        let mut nan = whole;
        let at = nan.len() - 4 * 9; // first velocity component of sphere 0... a position
        nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        std::fs::write(&path, &nan).unwrap();
        assert!(read_checkpoint(&path).is_err());
    }
}
