//! Recording steps into a compute pass phase by phase, and the batch driver that submits them.

use super::schedule::{
    MAX_REBIN_SHARE, RELAYOUT_EVERY, Rebin, SKIN_RETRY_STEPS, StepKind, submissions,
};
use super::*;

/// The phases of a step, in order.
#[derive(Debug, Clone, Copy)]
pub(super) enum Phase {
    /// Sort of the spheres by cell (the dense build's counts come from the last step).
    Build,
    /// Detection with the contact forces.
    Resolve,
    /// The clumps' step, walls, gravity and integration (the dense build's also counts the
    /// spheres into their cells for the next step).
    Integrate,
}

impl Phase {
    pub(super) const ALL: [Phase; 3] = [Phase::Build, Phase::Resolve, Phase::Integrate];

    pub(super) fn label(self) -> &'static str {
        match self {
            Phase::Build => "mochi.dem.build",
            Phase::Resolve => "mochi.dem.resolve",
            Phase::Integrate => "mochi.dem.integrate",
        }
    }
}

impl GridStepper {
    /// Records one phase of a step of kind `kind` from `from` into `pass` (without a skin, the
    /// dense build's spheres counted already: see [`counted`](Self::counted); with one, the
    /// step re-bins where `rebin` is `Always`, else where the GPU finds it must).
    pub(super) fn record_phase(
        &self,
        pass: &mut wgpu::ComputePass,
        from: Turn,
        kind: StepKind,
        rebin: Rebin,
        phase: Phase,
    ) {
        if kind == StepKind::Skin {
            return self.record_skin_phase(pass, from.set, rebin, phase);
        }
        let binds = &self.laid_out.binds;
        let b = &binds[from.set];
        let p = &self.res.pipelines;
        let binning = (kind == StepKind::Binning).then(|| {
            let own = b.binning.as_ref().expect("a step with binning steps");
            let bin_index = p.bin_index.as_ref().expect("a step with binning steps");
            (own, bin_index)
        });
        match phase {
            Phase::Build => {
                if self.build() == BuildKind::Sorted {
                    gpu::record(pass, &p.bin_first, &b.bin_first, self.groups);
                }
                self.laid_out.record_scan(pass, None);
                match binning {
                    Some((own, bin_index)) => {
                        gpu::record(pass, bin_index, &own.bin_index, self.groups)
                    }
                    None => gpu::record(pass, &p.bin_last, &b.bin_last, self.groups),
                }
            }
            Phase::Resolve => {
                let r = binning.map_or(&b.resolving, |(own, _)| &own.resolving);
                if let (Some(pipeline), Some(bind)) = (&p.name_places, &r.name_places) {
                    gpu::record(pass, pipeline, bind, self.groups);
                }
                let resolve = match (&p.listing, &r.list_near) {
                    (Some([list_near, resolve_near]), Some(bind)) => {
                        gpu::record(pass, list_near, bind, self.groups);
                        resolve_near
                    }
                    _ => &p.resolve,
                };
                gpu::record(pass, resolve, &r.resolve[from.parity], self.groups);
                if let (Some(pipelines), Some(binds)) = (&p.mesh, &r.mesh) {
                    for (pipeline, bind) in pipelines.iter().zip(&binds[from.parity]) {
                        gpu::record(pass, pipeline, bind, self.groups);
                    }
                }
            }
            // A binning step integrates the set it is on, as the sorting step from the other
            // set does.
            // The clumps' step places their components first (the integration leaves them).
            Phase::Integrate => {
                let on = match kind {
                    StepKind::Binning => &binds[1 - from.set],
                    _ => b,
                };
                if let (Some((pipeline, groups)), Some(bind)) = (&p.clumps, &on.clumps) {
                    gpu::record(pass, pipeline, bind, *groups);
                }
                gpu::record(pass, &p.integrate, &on.integrate, self.groups)
            }
        }
    }

    /// Records one phase of a step with a skin whose state is on set `on`: where it re-bins
    /// (`rebin`, or the GPU's decision), the count, the scan, the scatter into the other set
    /// and the copy back; then the contact pass and the integration on `on`, as a sorting
    /// step's on a sorted set.
    pub(super) fn record_skin_phase(
        &self,
        pass: &mut wgpu::ComputePass,
        on: usize,
        rebin: Rebin,
        phase: Phase,
    ) {
        let binds = &self.laid_out.binds;
        let (b, p) = (&binds[on], &self.res.pipelines);
        let own = b.skin.as_ref().expect("a step with a skin");
        let pipelines = p.skin.as_ref().expect("a step with a skin");
        let skin = self.res.skin.as_ref().expect("a step with a skin");
        match phase {
            Phase::Build => {
                let passes = [
                    (&p.bin_first, &b.bin_first),
                    (&p.bin_last, &b.bin_last),
                    (&pipelines.bin_return, &own.bin_return),
                ];
                if rebin == Rebin::IfMoved {
                    gpu::record(pass, &pipelines.begin_step, &own.begin_step, (1, 1));
                    skin.dispatch_spheres(pass, passes[0].0, passes[0].1);
                    self.laid_out.record_scan(pass, Some(skin.blocks_args()));
                    for (pipeline, bind) in &passes[1..] {
                        skin.dispatch_spheres(pass, pipeline, bind);
                    }
                } else {
                    gpu::record(pass, &pipelines.begin_binning, &own.begin_binning, (1, 1));
                    gpu::record(pass, passes[0].0, passes[0].1, self.groups);
                    self.laid_out.record_scan(pass, None);
                    for (pipeline, bind) in &passes[1..] {
                        gpu::record(pass, pipeline, bind, self.groups);
                    }
                }
            }
            // The sorting step's contact pass from the other set resolves `on`.
            Phase::Resolve => {
                let resolve = &binds[1 - on].resolving.resolve[0];
                gpu::record(pass, &p.resolve, resolve, self.groups)
            }
            Phase::Integrate => {
                gpu::record(pass, &pipelines.integrate, &own.integrate, self.groups)
            }
        }
    }

    /// Records `steps` steps into `encoder` and moves the clock past them; returns how many
    /// were marked phase by phase. With a timer, the first step is recorded phase by phase
    /// between timestamps (see [`StepTimer`]), the others share a compute pass for every
    /// `submit_every` of them (all in one where `None`), each but the last submitted as soon as
    /// it is recorded (`encoder` then holds the last), and the batch's end is marked and
    /// resolved.
    pub(super) fn encode_steps(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        steps: u32,
        submit_every: Option<u32>,
    ) -> Result<u32> {
        let timer = self.timer.as_ref();
        let mut turn = self.turn();
        self.batch_start = (self.current, self.parity, self.sort_next);
        let mut profiled = 0;
        let schedule = self.schedule();
        let skinned = schedule.skinned;
        // With a skin the first step re-bins where its places may be stale or its phases are
        // timed; the counts are zero between steps but where the layout or the state changed.
        let first_rebin = match self.counted && timer.is_none() {
            true => Rebin::IfMoved,
            false => Rebin::Always,
        };
        // A step with a skin re-bins where the batch's first step must or [`Sorting`] sorts.
        let rebin_at = |step: u32| match step == 0 && first_rebin == Rebin::Always {
            true => Rebin::Always,
            false if schedule.sorts(step) => Rebin::Always,
            false => Rebin::IfMoved,
        };
        if let Some(skin) = self.res.skin.as_ref().filter(|_| skinned) {
            skin.prepare(
                &self.res.gpu,
                self.groups,
                self.laid_out.layout.scan_blocks(),
            );
        }
        if let Sorter::Dense { cell_table, .. } = &self.laid_out.sorter
            && !self.counted
        {
            // What a step counted before the layout or the state changed is cleared; without a
            // skin the spheres are counted afresh, ahead of the batch's first step and its
            // timestamps (with one, that step re-bins and counts them itself).
            encoder.clear_buffer(&cell_table.counts, 0, None);
            if !skinned {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("mochi.dem.count"),
                    timestamp_writes: None,
                });
                let b = &self.laid_out.binds[turn.set];
                gpu::record(
                    &mut pass,
                    &self.res.pipelines.bin_first,
                    &b.bin_first,
                    self.groups,
                );
            }
        }
        if timer.is_some() {
            let kind = schedule.kind_of_step(0);
            StepTimer::mark(timer, encoder, 0, 0);
            for (k, phase) in Phase::ALL.into_iter().enumerate() {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(phase.label()),
                    timestamp_writes: None,
                });
                self.record_phase(&mut pass, turn, kind, rebin_at(0), phase);
                drop(pass);
                StepTimer::mark(timer, encoder, 0, k as u32 + 1);
            }
            turn = schedule.turn_after(kind, turn);
            profiled = 1;
        }
        let mut k = profiled;
        while k < steps {
            let end = submit_every.map_or(steps, |every| (k + every).min(steps));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("mochi.dem.steps"),
                timestamp_writes: None,
            });
            for step in k..end {
                let kind = schedule.kind_of_step(step);
                for phase in Phase::ALL {
                    self.record_phase(&mut pass, turn, kind, rebin_at(step), phase);
                }
                turn = schedule.turn_after(kind, turn);
            }
            drop(pass);
            k = end;
            if k < steps {
                let gpu = &self.res.gpu;
                let next = gpu.device.create_command_encoder(&Default::default());
                let done = std::mem::replace(encoder, next);
                gpu.checked("running DEM steps", || gpu.queue.submit([done.finish()]))?;
            }
        }
        let timer = self.timer.as_ref();
        if let Some(t) = timer {
            t.end(encoder, profiled);
        }
        (self.current, self.parity) = (turn.set, turn.parity);
        self.step += steps as u64;
        self.sort_next = false;
        self.counted = self.build() == BuildKind::Dense;
        Ok(profiled)
    }

    /// Records a batch of `steps` steps that ends by reducing its bounds and copying its
    /// results for the host, and submits it; with the time its recording took \[ms\]. The
    /// granular step's batch first keeps what it begins from, for a redo.
    pub(super) fn submit_batch(&mut self, steps: u32) -> Result<(InFlight, f64)> {
        let recording = std::time::Instant::now();
        let mut encoder = self
            .res
            .gpu
            .device
            .create_command_encoder(&Default::default());
        let turn = self.turn();
        let res = &mut self.res;
        if let Some(g) = &mut res.granular {
            let set = &res.sets[turn.set];
            let state = [&set.pos, &set.lo, &set.vel, &set.ids, &res.clock];
            g.begin_batch(&res.gpu, &mut encoder, turn, &state);
        }
        // The granular step's batches, waited for one by one, are split into submissions
        // where the GPU would otherwise wait for their recording.
        let submit_every = self.res.granular.as_ref().and(self.submit_every);
        let profiled = self.encode_steps(&mut encoder, steps, submit_every)?;
        self.record_bounds(&mut encoder);
        let timer = self.timer.as_ref().map(|t| (t, profiled));
        let skin = self.res.skin.as_ref().filter(|_| self.skinned());
        let rebins = skin.map(|s| (&s.state, Skin::REBINS_AT));
        self.readback.record(
            &mut encoder,
            &self.res.counters,
            rebins,
            Some(&self.res.bounds),
            timer,
        );
        let rebinning = skin.map(|_| steps);
        let recorded_ms = recording.elapsed().as_secs_f64() * 1e3;
        let batch = self
            .readback
            .submit(&self.res.gpu, encoder, profiled, rebinning)?;
        Ok((batch, recorded_ms))
    }

    /// `steps` steps in batches, every variant's driver. A layout falls due at a batch's start
    /// and is made from the bounds of the last batch that finished. The paper's step keeps one
    /// batch in flight while it records the next (its layout's bounds are then one batch old:
    /// spheres outside a layout are clamped into its border cells, exact, so a layout need not
    /// be fresh). The granular step waits for each batch: one in which a sphere had more
    /// contacts than history slots is redone, with more slots, from the state it began from.
    pub(super) fn advance_batches(&mut self, steps: u32) -> Result<Advance> {
        if self.stale {
            self.relayout()?;
        }
        let waits = self.res.granular.is_some();
        let mut times = StageTimes::default();
        let mut timed = self.timer.is_some();
        let mut contacts = 0;
        let mut left = steps;
        let mut in_flight = None;
        loop {
            let submitted = match left {
                0 => None,
                _ => {
                    if self.step >= self.laid_out.at + RELAYOUT_EVERY
                        && let Some(keys) = self.last_bounds.take()
                    {
                        let (lo, hi) = self.decode_bounds(&keys)?;
                        self.layout_over(lo, hi)?;
                    }
                    let batch = left.min(MAX_BATCH).min(RELAYOUT_EVERY as u32);
                    left -= batch;
                    Some((self.submit_batch(batch)?, batch))
                }
            };
            let finishing = match waits {
                true => submitted,
                false => std::mem::replace(&mut in_flight, submitted),
            };
            let Some(((done, recorded_ms), batch)) = finishing else {
                match in_flight {
                    Some(_) => continue,
                    None => break,
                }
            };
            let results = self.readback.finish(&self.res.gpu, done)?;
            if waits && self.redo_grown(batch)? {
                left += batch;
                continue;
            }
            contacts = results.contacts;
            if let Some((steps, rebins)) = results.rebins {
                self.rebinned.0 += steps as u64;
                self.rebinned.1 += rebins as u64;
                // Off from the next layout on where it re-binned too often.
                if rebins as f64 > MAX_REBIN_SHARE * steps as f64 {
                    self.skin_off_until = self.step + SKIN_RETRY_STEPS;
                }
            }
            self.last_bounds = Some(results.bounds);
            if waits {
                self.submit_every = submissions(results.times.as_ref(), recorded_ms);
            }
            match results.times {
                Some(t) => times.add(&t),
                None => timed = false,
            }
        }
        Ok(Advance {
            steps,
            contacts,
            times,
            clock: if timed { Clock::Gpu } else { Clock::None },
        })
    }

    /// After the granular step's last batch of `steps` steps: where a sphere had more
    /// contacts than history slots, the batch is undone (the clock, the state set and the
    /// parity back to its start, its state restored) with more slots, and `true` says to run
    /// it again.
    fn redo_grown(&mut self, steps: u32) -> Result<bool> {
        let need = match &self.res.granular {
            Some(g) => g.overflow(&self.res.gpu)?,
            None => None,
        };
        let Some(need) = need else {
            return Ok(false);
        };
        self.step -= steps as u64;
        (self.current, self.parity, self.sort_next) = self.batch_start;
        self.counted = false;
        let turn = self.turn();
        let res = &mut self.res;
        if let Some(g) = &mut res.granular {
            let set = &res.sets[turn.set];
            let state = [&set.pos, &set.lo, &set.vel, &set.ids, &res.clock];
            g.restore_grown(&res.gpu, (turn, &state), need, &mut res.dem_uniform)?;
        }
        self.rebind();
        Ok(true)
    }
}
