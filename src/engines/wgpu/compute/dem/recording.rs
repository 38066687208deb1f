//! Recording steps into a compute pass phase by phase, and the batch drivers that submit them.

use super::schedule::{
    MAX_REBIN_SHARE, RELAYOUT_EVERY, Rebin, SKIN_RETRY_STEPS, StepKind, submissions,
};
use super::*;

impl RedoableBatch for GridStepper {
    fn batch_parts(&mut self) -> BatchParts<'_> {
        let (turn, set) = (self.turn(), &self.sets[self.current]);
        let state = vec![&set.pos, &set.lo, &set.vel, &set.ids, &self.clock];
        let (granular, params) = (self.granular.as_mut(), &mut self.dem_uniform);
        (&self.gpu, granular, turn, state, params)
    }

    fn record_batch(
        &mut self,
        mut encoder: wgpu::CommandEncoder,
        steps: u32,
    ) -> Result<(u64, Option<StageTimes>)> {
        let recording = std::time::Instant::now();
        let profiled = self.encode_steps(&mut encoder, steps, self.submit_every)?;
        let recorded_ms = recording.elapsed().as_secs_f64() * 1e3;
        let gpu = &self.gpu;
        let timer = self.timer.as_ref();
        gpu.checked("running DEM steps", || gpu.queue.submit([encoder.finish()]))?;
        let contacts = gpu.read::<u32>(&self.counters, 1)?[0] as u64;
        let times = timer.map(|t| t.read(gpu, profiled)).transpose()?;
        self.submit_every = submissions(times.as_ref(), recorded_ms);
        Ok((contacts, times))
    }

    fn rewind(&mut self, steps: u32) {
        self.step -= steps as u64;
        (self.current, self.parity, self.sort_next) = self.batch_start;
        self.counted = false;
    }

    fn rebind(&mut self) {
        self.binds = Some([self.make_binds(0), self.make_binds(1)]);
    }
}

/// The phases of a step, in order.
#[derive(Debug, Clone, Copy)]
pub(super) enum Phase {
    /// Sort of the spheres by cell (the dense build's counts come from the last step).
    Build,
    /// Detection with the contact forces.
    Resolve,
    /// Walls, gravity and integration (the dense build's also counts the spheres into their
    /// cells for the next step).
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
        let binds = self.binds.as_ref().expect("laid out");
        let b = &binds[from.set];
        let p = &self.pipelines;
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
                self.record_scan(pass, None);
                match binning {
                    Some((own, bin_index)) => {
                        gpu::record(pass, bin_index, &own.bin_index, self.groups)
                    }
                    None => gpu::record(pass, &p.bin_last, &b.bin_last, self.groups),
                }
            }
            Phase::Resolve => {
                let r = binning.map_or(&b.resolving, |(own, _)| &own.resolving);
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
            Phase::Integrate => {
                let integrate = match kind {
                    StepKind::Binning => &binds[1 - from.set].integrate,
                    _ => &b.integrate,
                };
                gpu::record(pass, &p.integrate, integrate, self.groups)
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
        let binds = self.binds.as_ref().expect("laid out");
        let (b, p) = (&binds[on], &self.pipelines);
        let own = b.skin.as_ref().expect("a step with a skin");
        let pipelines = p.skin.as_ref().expect("a step with a skin");
        let skin = self.skin.as_ref().expect("a step with a skin");
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
                    self.record_scan(pass, Some(skin.blocks_args()));
                    for (pipeline, bind) in &passes[1..] {
                        skin.dispatch_spheres(pass, pipeline, bind);
                    }
                } else {
                    gpu::record(pass, &pipelines.begin_binning, &own.begin_binning, (1, 1));
                    gpu::record(pass, passes[0].0, passes[0].1, self.groups);
                    self.record_scan(pass, None);
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

    /// Records the sorter's pass between the binning's first and last: the scan of the cell
    /// table (its dispatch read from `indirect` where given), or the sort of the keys.
    pub(super) fn record_scan(
        &self,
        pass: &mut wgpu::ComputePass,
        indirect: Option<(&wgpu::Buffer, u64)>,
    ) {
        match &self.sorter {
            Sorter::Dense {
                scan, scan_bind, ..
            } => {
                let binds = scan_bind.as_ref().expect("laid out");
                match indirect {
                    Some(args) => scan.record_indirect(pass, binds, args),
                    None => scan.record(pass, binds, &self.layout),
                }
            }
            Sorter::Sorted { prepared, .. } => prepared.as_ref().expect("laid out").record(pass),
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
        if let Some(skin) = self.skin.as_ref().filter(|_| skinned) {
            skin.prepare(&self.gpu, self.groups, self.layout.scan_blocks());
        }
        if let Sorter::Dense { cell_table, .. } = &self.sorter
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
                let b = &self.binds.as_ref().expect("laid out")[turn.set];
                gpu::record(
                    &mut pass,
                    &self.pipelines.bin_first,
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
                let gpu = &self.gpu;
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

    /// Records a batch of `steps` steps of the paper's step that ends by reducing its bounds
    /// and copying its results for the host, and submits it.
    pub(super) fn submit_batch(&mut self, steps: u32) -> Result<InFlight> {
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        let profiled = self.encode_steps(&mut encoder, steps, None)?;
        self.record_bounds(&mut encoder);
        let timer = self.timer.as_ref().map(|t| (t, profiled));
        let skin = self.skin.as_ref().filter(|_| self.skinned());
        let rebins = skin.map(|s| (&s.state, Skin::REBINS_AT));
        self.readback.record(
            &mut encoder,
            &self.counters,
            rebins,
            Some(&self.bounds),
            timer,
        );
        let rebinning = skin.map(|_| steps);
        self.readback
            .submit(&self.gpu, encoder, profiled, rebinning)
    }

    /// The paper's step, `steps` steps in batches kept in flight: batch k + 1 is recorded and
    /// submitted before the host waits for batch k. A layout falls due at a batch's start; it
    /// is made from the bounds of the last batch that finished (one batch old while another
    /// runs: spheres outside a layout are clamped into its border cells, exact, so a layout
    /// need not be fresh).
    pub(super) fn advance_paper(&mut self, steps: u32) -> Result<Advance> {
        if self.laid_out_at.is_none() {
            self.relayout()?;
        }
        let mut times = StageTimes::default();
        let mut timed = self.timer.is_some();
        let mut contacts = 0;
        let mut left = steps;
        let mut in_flight: Option<InFlight> = None;
        loop {
            let next = if left > 0 {
                let laid_out_at = self.laid_out_at.unwrap_or(self.step);
                if self.step >= laid_out_at + RELAYOUT_EVERY
                    && let Some(keys) = self.last_bounds.take()
                {
                    let (lo, hi) = self.decode_bounds(&keys)?;
                    self.layout_over(lo, hi)?;
                }
                let batch = left.min(MAX_BATCH).min(RELAYOUT_EVERY as u32);
                left -= batch;
                Some(self.submit_batch(batch)?)
            } else {
                None
            };
            if let Some(done) = in_flight.take() {
                let results = self.readback.finish(&self.gpu, done)?;
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
                match results.times {
                    Some(t) => times.add(&t),
                    None => timed = false,
                }
            }
            match next {
                Some(batch) => in_flight = Some(batch),
                None => break,
            }
        }
        Ok(Advance {
            steps,
            contacts,
            times,
            clock: if timed { Clock::Gpu } else { Clock::None },
        })
    }
}
