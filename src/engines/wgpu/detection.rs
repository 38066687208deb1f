//! What the two wgpu engines' detection layers share: [`WgpuDetection`], the build, pair
//! output and timing, which differ only in the structure they build and the shader they search
//! it with.

use crate::detect::BackendInfo;
use crate::error::{Error, Result};
use crate::gpu::pair_output::{PairOutput, TakePairs};
use crate::gpu::pair_sort::PairSort;
use crate::gpu::timer::{GpuTimer, Span};
use crate::gpu::{self, Gpu};
use crate::proxy::ProxyMode;
use crate::spheres::Spheres;
use crate::types::{DetectStats, GpuTimes};

/// Timer spans of a build and of a detection pass.
const BUILD_SPAN: Span = Span(0);
const DETECT_SPAN: Span = Span(1);

/// A wgpu engine's detection state around its structure `S`: the device, the last build, and
/// the timer of builds and detections, read only when [`gpu_times`](Self::gpu_times) asks (a
/// caller that never asks, as the Python `Detector`, waits for no read-back of them).
pub(crate) struct WgpuDetection<S> {
    pub gpu: Gpu,
    /// Backend name, as in [`BackendInfo::name`] (for messages).
    name: &'static str,
    built: Option<Built<S>>,
    /// Sorts the pairs of every detection.
    sort: PairSort,
    timer: Option<GpuTimer>,
    /// Whether the timer's spans hold the current build's and detection's times.
    timed: Timed,
}

/// Which of the timer's spans belong to the current build and its last detection.
#[derive(Debug, Clone, Copy, Default)]
struct Timed {
    build: bool,
    detect: bool,
}

/// What one build leaves on the GPU.
struct Built<S> {
    n: u32,
    mode: ProxyMode,
    /// `None` for an empty set.
    structure: Option<S>,
    output: PairOutput,
}

/// The detection shader of an engine, dispatched once per sphere.
pub(crate) struct DetectKernel<'a> {
    /// Label of the pipeline, its bind group and its pass.
    pub label: &'a str,
    pub pipeline: &'a wgpu::ComputePipeline,
    /// Workgroup size, as in the shader.
    pub group: u32,
    /// What a failure interrupted, in words.
    pub what: &'a str,
}

/// What one run of the detection shader is given.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DetectRun {
    /// Spheres and mode of the build.
    pub n: u32,
    pub mode: ProxyMode,
    /// Pairs the output has room for (0 when only counting).
    pub capacity: u32,
    /// Invocations per dispatch row (2-D dispatch).
    pub row: u32,
}

impl<S> WgpuDetection<S> {
    /// No build yet; timed where `gpu` has timestamps inside encoders.
    pub fn new(name: &'static str, gpu: Gpu) -> Self {
        WgpuDetection {
            timer: GpuTimer::new(&gpu, 2),
            sort: PairSort::new(&gpu),
            gpu,
            name,
            built: None,
            timed: Timed::default(),
        }
    }

    /// [`BackendInfo`] of this device with `max_spheres`.
    pub fn info(&self, max_spheres: u64) -> BackendInfo {
        BackendInfo {
            name: self.name,
            device: gpu::describe(&self.gpu.info),
            max_spheres,
        }
    }

    /// Starts a build of `spheres`: refuses more than `max_spheres`; records an empty set's
    /// build and returns `None` for it, else the sphere count.
    pub fn begin_build(
        &mut self,
        spheres: Spheres<'_>,
        mode: ProxyMode,
        max_spheres: u64,
    ) -> Result<Option<u32>> {
        let n = spheres.len() as u64;
        if n > max_spheres {
            return Err(Error::TooLarge {
                what: format!("spheres for {} on {}", self.name, self.gpu.info.name),
                got: n,
                limit: max_spheres,
            });
        }
        if n == 0 {
            self.built = Some(Built {
                n: 0,
                mode,
                structure: None,
                output: PairOutput::new(&self.gpu, 1),
            });
            return Ok(None);
        }
        Ok(Some(n as u32))
    }

    /// The last build's structure and output where `fits` accepts that structure, else new ones
    /// (the structure from `allocate`, room for `n` pairs or 1024).
    pub fn reuse_or_allocate(
        &mut self,
        n: u32,
        fits: impl FnOnce(&S) -> bool,
        allocate: impl FnOnce(&Gpu) -> S,
    ) -> Result<(S, PairOutput)> {
        match self.built.take() {
            Some(Built {
                structure: Some(s),
                output,
                ..
            }) if fits(&s) => Ok((s, output)),
            _ => {
                let gpu = &self.gpu;
                gpu.checked(&format!("allocating the {} buffers", self.name), || {
                    (allocate(gpu), PairOutput::new(gpu, n.max(1024)))
                })
            }
        }
    }

    /// Records the build of `structure` over `n` spheres in `mode` with `record` (which may also
    /// upload), submits it timed and keeps it as the current build. Not waited for: a caller
    /// whose build's time and errors should be its own waits ([`Gpu::wait`]); else the next
    /// read-back waits for it.
    pub fn submit_build(
        &mut self,
        what: &str,
        (n, mode): (u32, ProxyMode),
        (structure, output): (S, PairOutput),
        record: impl FnOnce(&Gpu, &S, &mut wgpu::CommandEncoder),
    ) -> Result<()> {
        let gpu = &self.gpu;
        let timer = self.timer.as_ref();
        gpu.checked(what, || {
            gpu.submit_timed(timer, BUILD_SPAN, |encoder| {
                record(gpu, &structure, encoder)
            });
        })?;
        self.timed = Timed {
            build: timer.is_some(),
            detect: false,
        };
        self.built = Some(Built {
            n,
            mode,
            structure: Some(structure),
            output,
        });
        Ok(())
    }

    /// Sphere count and mode of the current build, if any.
    pub fn built(&self) -> Option<(usize, ProxyMode)> {
        self.built.as_ref().map(|b| (b.n as usize, b.mode))
    }

    /// The current build's structure (`None` before a build and for an empty set).
    pub fn structure(&self) -> Option<&S> {
        self.built.as_ref()?.structure.as_ref()
    }

    /// Runs `kernel` over the current build; with `take`, grows the output until every pair
    /// fits and hands it the pairs. `bind` writes the run's uniform and returns the kernel's bind group (the output's
    /// [`COUNTERS`](crate::gpu::pair_output::COUNTERS) and
    /// [`PAIRS`](crate::gpu::pair_output::PAIRS) included).
    pub fn detect(
        &mut self,
        take: Option<TakePairs<'_>>,
        kernel: DetectKernel,
        bind: impl Fn(&Gpu, &S, &PairOutput, DetectRun) -> wgpu::BindGroup,
    ) -> Result<DetectStats> {
        let gpu = &self.gpu;
        let built = self
            .built
            .as_mut()
            .ok_or_else(|| Error::Usage("detection asked for before build".into()))?;
        let Some(structure) = built.structure.as_ref() else {
            if let Some(take) = take {
                take(&[]);
            }
            return Ok(DetectStats::default());
        };
        let (x, y) = gpu.grid(built.n, kernel.group);
        let (n, mode) = (built.n, built.mode);
        let timer = self.timer.as_ref();
        let sort = (&mut self.sort, n);
        let result = built.output.detect(gpu, take, sort, |output, capacity| {
            let run = DetectRun {
                n,
                mode,
                capacity,
                row: x * kernel.group,
            };
            gpu.checked(kernel.what, || {
                let group = bind(gpu, structure, output, run);
                gpu.submit_timed(timer, DETECT_SPAN, |encoder| {
                    gpu.dispatch(encoder, kernel.label, kernel.pipeline, &group, (x, y));
                });
            })
        })?;
        self.timed.detect = timer.is_some();
        Ok(result)
    }

    /// GPU time of the last build and detection, where measured.
    pub fn gpu_times(&self) -> GpuTimes {
        let (Some(timer), Timed { build, detect }) = (&self.timer, self.timed) else {
            return GpuTimes::default();
        };
        if !build && !detect {
            return GpuTimes::default();
        }
        // Both spans in one read-back; a failed read measures nothing.
        match timer.spans_ms(&self.gpu, &[BUILD_SPAN, DETECT_SPAN]) {
            Ok(ms) => GpuTimes {
                build_ms: build.then_some(ms[0]),
                detect_ms: detect.then_some(ms[1]),
            },
            Err(_) => GpuTimes::default(),
        }
    }
}
