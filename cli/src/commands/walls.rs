//! `mochi simulate`'s mesh-wall outputs: each wall's surface (`wall_{k}.vtp` once for a wall
//! that never moves, `wall_{step}_{k}.vtp` at every frame for one that does), listed per frame in
//! `walls.pvd` beside `series.pvd`, and with every frame the force and torque the spheres
//! exerted on each wall in the last step (`walls.csv`); and what the inflows and outflows did
//! between frames (`flow.csv`). Each frame adds its own entries and rows to the files.

use anyhow::{Context, Result};
use mochi::dem::flow::FlowCounts;
use mochi::dem::walls::{WallLoad, WallSet};
use mochi::io::{self, SeriesEntry, WallLoadRow};
use std::path::{Path, PathBuf};

/// Where the walls' outputs go and what they show.
pub struct WallOutputs {
    walls: WallSet,
    dir: PathBuf,
    /// The step of the last frame in `walls.pvd`.
    last_step: Option<u64>,
}

impl WallOutputs {
    /// Outputs for the mesh walls of `walls` in the run folder `out` (`None` without any): the
    /// surfaces of the walls that never move, `walls.pvd` listing the frames `kept` (those a
    /// resumed run keeps, else none) and `walls.csv` started anew or, on a resume from time
    /// `resume_time`, kept up to that time.
    pub fn start(
        out: &Path,
        walls: &WallSet,
        kept: &[SeriesEntry],
        resume_time: Option<f64>,
    ) -> Result<Option<Self>> {
        if walls.meshes.is_empty() {
            return Ok(None);
        }
        io::start_log(
            &out.join(io::WALL_LOADS),
            io::WALL_LOADS_HEADER,
            resume_time,
        )?;
        let outputs = Self {
            walls: walls.clone(),
            dir: out.to_owned(),
            last_step: kept.last().map(|e| e.step),
        };
        let rest = walls.poses_at(0.0);
        for (k, wall) in walls.meshes.iter().enumerate() {
            if !wall.motion.moves() {
                let file = out.join(io::wall_file_name(None, k));
                io::write_surface_vtp(&file, &wall.triangles_at(&rest[k]))?;
            }
        }
        let entries: String = kept.iter().map(|e| outputs.index_entries(e)).collect();
        io::write_collection(&out.join(io::WALLS_INDEX), &entries)?;
        Ok(Some(outputs))
    }

    /// The file of wall `k` at `step`.
    fn file_name(&self, step: u64, k: usize) -> String {
        let moves = self.walls.meshes[k].motion.moves();
        io::wall_file_name(moves.then_some(step), k)
    }

    /// The lines of `walls.pvd` for the frame `frame`: a part per wall.
    fn index_entries(&self, frame: &SeriesEntry) -> String {
        (0..self.walls.meshes.len())
            .map(|k| io::entry_line(frame.time, k, &self.file_name(frame.step, k)))
            .collect()
    }

    /// Writes the moving walls at `step` (time `step · dt`), adds the frame to the index (the
    /// frames `frames`, the last of them this one), and appends the rows of `loads`.
    pub fn write(
        &mut self,
        frames: &[SeriesEntry],
        step: u64,
        dt: f32,
        loads: &[WallLoad],
    ) -> Result<()> {
        let time = step as f64 * dt as f64;
        let poses = self.walls.poses_at(time);
        for (k, wall) in self.walls.meshes.iter().enumerate() {
            if wall.motion.moves() {
                let file = self.dir.join(self.file_name(step, k));
                io::write_surface_vtp(&file, &wall.triangles_at(&poses[k]))?;
            }
        }
        let index = self.dir.join(io::WALLS_INDEX);
        match frames.last() {
            Some(frame) if self.last_step.is_none_or(|last| last < frame.step) => {
                io::append_entries(&index, &self.index_entries(frame))?;
            }
            _ => {
                let entries: String = frames.iter().map(|e| self.index_entries(e)).collect();
                io::write_collection(&index, &entries)?;
            }
        }
        self.last_step = frames.last().map(|e| e.step);
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
    /// (time, mass removed since the run started) at each row.
    discharge: Vec<(f64, f64)>,
}

impl FlowLog {
    /// The log in the run folder `out` (`None` for a step without flows, whose counts from the
    /// run's start are `counts`), started anew or, on a resume from `resume_time`, kept up to
    /// that time and going on from `logged`, the counts at its last kept row (the checkpoint's;
    /// `None` for a checkpoint that did not save them: then from the resume).
    pub fn start(
        out: &Path,
        counts: Option<FlowCounts>,
        resume_time: Option<f64>,
        logged: Option<FlowCounts>,
    ) -> Result<Option<Self>> {
        let Some(now) = counts else {
            return Ok(None);
        };
        let path = out.join(io::FLOW_LOG);
        io::start_log(&path, io::FLOW_LOG_HEADER, resume_time)?;
        let mut discharge = Vec::new();
        if resume_time.is_some() {
            // The mass removed up to each kept row, summed from the rows.
            let text = std::fs::read_to_string(&path)
                .with_context(|| format!("reading {}", path.display()))?;
            let mut removed = 0.0;
            for row in text.lines().skip(1) {
                let values: Vec<f64> = row.split(',').filter_map(|x| x.parse().ok()).collect();
                if let [time, .., mass] = values[..] {
                    removed += mass;
                    discharge.push((time, removed));
                }
            }
        }
        Ok(Some(Self {
            path,
            last: logged.unwrap_or(now),
            discharge,
        }))
    }

    /// The counts at the last row (as checkpoints save them).
    pub fn last(&self) -> FlowCounts {
        self.last
    }

    /// Adds the row of time `time` with `spheres` present and the step's counts `now`.
    pub fn write(&mut self, time: f64, spheres: usize, now: FlowCounts) -> Result<()> {
        let was = self.last;
        let line = format!(
            "{time:e},{spheres},{},{},{},{:e}\n",
            now.inserted.saturating_sub(was.inserted),
            now.refused.saturating_sub(was.refused),
            now.removed.saturating_sub(was.removed),
            now.removed_mass - was.removed_mass
        );
        io::append_log(&self.path, &line)?;
        self.last = now;
        self.discharge.push((time, now.removed_mass));
        Ok(())
    }

    /// (time, mass removed since the run started) at each row so far.
    pub fn discharge(&self) -> &[(f64, f64)] {
        &self.discharge
    }
}
