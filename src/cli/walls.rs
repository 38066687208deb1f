//! `mochi simulate`'s mesh-wall outputs: with every frame, each wall's surface where it is then
//! (`wall_{step}_{k}.vtp`, listed in `walls.pvd` beside `series.pvd`) and the force and torque
//! the spheres exerted on it in the last step (`walls.csv`); and what the inflows and
//! outflows did between frames (`flow.csv`).

use anyhow::Result;
use mochi::dem::flow::FlowCounts;
use mochi::dem::walls::{WallLoad, WallSet};
use mochi::io::{self, SeriesEntry, WallLoadRow};
use std::path::{Path, PathBuf};

/// Where the walls' outputs go and what they show.
pub struct WallOutputs {
    walls: WallSet,
    dir: PathBuf,
}

impl WallOutputs {
    /// Outputs for the mesh walls of `walls` in the run folder `out` (`None` without any),
    /// starting `walls.csv` anew or, on a resume from time `resume_time`, keeping its rows up
    /// to that time.
    pub fn start(out: &Path, walls: &WallSet, resume_time: Option<f64>) -> Result<Option<Self>> {
        if walls.meshes.is_empty() {
            return Ok(None);
        }
        io::start_log(
            &out.join(io::WALL_LOADS),
            io::WALL_LOADS_HEADER,
            resume_time,
        )?;
        Ok(Some(Self {
            walls: walls.clone(),
            dir: out.to_owned(),
        }))
    }

    /// Writes the walls at `step` (time `step · dt`), the index of the frames `frames`, and the
    /// rows of `loads`.
    pub fn write(
        &self,
        frames: &[SeriesEntry],
        step: u64,
        dt: f32,
        loads: &[WallLoad],
    ) -> Result<()> {
        let time = step as f64 * dt as f64;
        for (k, (wall, pose)) in self
            .walls
            .meshes
            .iter()
            .zip(self.walls.poses_at(time))
            .enumerate()
        {
            let points: Vec<[f32; 3]> = wall.triangles_at(&pose).concat();
            let triangles: Vec<[u32; 3]> = (0..points.len() as u32 / 3)
                .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
                .collect();
            let file = self.dir.join(io::wall_file_name(step, k));
            io::write_surface_vtp(&file, &points, &triangles)?;
        }
        io::write_walls_index(
            &self.dir.join(io::WALLS_INDEX),
            frames,
            self.walls.meshes.len(),
        )?;
        let rows: Vec<WallLoadRow> = loads
            .iter()
            .enumerate()
            .map(|(wall, l)| WallLoadRow {
                time,
                wall,
                force: l.force,
                torque: l.torque,
            })
            .collect();
        io::append_log(&self.dir.join(io::WALL_LOADS), &io::wall_load_lines(&rows))?;
        Ok(())
    }
}

/// `flow.csv`: what the inflows and outflows did between frames.
pub struct FlowLog {
    path: PathBuf,
    /// The counts at the previous row.
    last: FlowCounts,
    /// (time, mass removed since the log started) at each row.
    discharge: Vec<(f64, f64)>,
}

impl FlowLog {
    /// The log in the run folder `out` (`None` for a step without flows), started anew or, on
    /// a resume from `resume_time`, kept up to that time.
    pub fn start(
        out: &Path,
        counts: Option<FlowCounts>,
        resume_time: Option<f64>,
    ) -> Result<Option<Self>> {
        let Some(last) = counts else {
            return Ok(None);
        };
        let path = out.join(io::FLOW_LOG);
        io::start_log(&path, io::FLOW_LOG_HEADER, resume_time)?;
        Ok(Some(Self {
            path,
            last,
            discharge: Vec::new(),
        }))
    }

    /// Adds the row of time `time` with `spheres` present and the step's counts `now`.
    pub fn write(&mut self, time: f64, spheres: usize, now: FlowCounts) -> Result<()> {
        let was = self.last;
        let line = format!(
            "{time:e},{spheres},{},{},{},{:e}\n",
            now.inserted - was.inserted,
            now.refused - was.refused,
            now.removed - was.removed,
            now.removed_mass - was.removed_mass
        );
        io::append_log(&self.path, &line)?;
        self.last = now;
        self.discharge.push((time, now.removed_mass));
        Ok(())
    }

    /// (time, mass removed since the log started) at each row so far.
    pub fn discharge(&self) -> &[(f64, f64)] {
        &self.discharge
    }
}
