//! What a benchmark run found: one row per measurement, with the machine, the date and the
//! command, serialized as JSON (see [`SCHEMA_VERSION`]).

use super::plan::{BackendStatus, Experiment, Settings};
use super::stats::Spread;
use mochi::dem::Clock;
use mochi::dem::scene::SceneKind;
use mochi::engines::BackendKind;
use mochi::engines::wgpu::compute::Structure;
use mochi::numbers::significant;
use mochi::proxy::ProxyMode;
use mochi::scenes::Layout;
use serde::{Deserialize, Serialize};

/// Version of the JSON layout; raised whenever a field changes meaning or goes away. 2: experiment
/// 8's rows time the whole drop at dt 1e-4 from its start (each run from the start), experiment
/// 6's `polylog` rows a poured pile under the per-pair linear law; DEM rows say their time step,
/// the steps run before the timed ones and the steps timed; the report holds the peers' figures
/// of `--compare`.
pub const SCHEMA_VERSION: u32 = 2;

/// A whole benchmark run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// [`SCHEMA_VERSION`] of the writer.
    pub schema_version: u32,
    /// Version of mochi that measured.
    pub mochi_version: String,
    /// When the run started, UTC, ISO 8601.
    pub date: String,
    /// The command line, as typed.
    pub command: String,
    /// The host.
    pub machine: Machine,
    /// The settings of the run.
    pub settings: Settings,
    /// Every backend this build knows: its device, or why it was left out.
    pub backends: Vec<BackendStatus>,
    /// Detection rows (experiment 1).
    pub detect: Vec<DetectRow>,
    /// DEM rows (experiments 2–8).
    pub dem: Vec<DemRow>,
    /// Measurements a backend could not make, and why.
    pub skipped: Vec<Skipped>,
    /// The performance targets, checked against the rows (the bench's `targets::check`).
    pub targets: Vec<Check>,
    /// Other codes' figures (`--compare`) beside mochi's rows of the same experiment.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub comparisons: Vec<Comparison>,
}

/// The host that ran the benchmark.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Machine {
    /// Operating system.
    pub os: String,
    /// CPU architecture.
    pub arch: String,
    /// CPU model, where the OS says.
    pub cpu: Option<String>,
    /// Threads the cpu backend uses.
    pub threads: usize,
}

impl Machine {
    /// This machine.
    pub fn here() -> Machine {
        let cpu = std::fs::read_to_string("/proc/cpuinfo")
            .ok()
            .and_then(|info| {
                info.lines()
                    .find_map(|l| l.strip_prefix("model name"))
                    .and_then(|l| l.split_once(':'))
                    .map(|(_, model)| model.trim().to_owned())
            });
        Machine {
            os: std::env::consts::OS.to_owned(),
            arch: std::env::consts::ARCH.to_owned(),
            cpu,
            threads: rayon::current_num_threads(),
        }
    }
}

/// One detection measurement: build and find every pair, repeated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectRow {
    /// Always [`Experiment::Dcd`].
    pub experiment: Experiment,
    /// The backend.
    #[serde(with = "mochi::names::by_name")]
    pub backend: BackendKind,
    /// Its device, in words.
    pub device: String,
    /// The scene.
    pub scene: SceneKind,
    /// Layout of the centres (`random`: overlaps allowed).
    pub layout: Layout,
    /// Spheres.
    pub n: usize,
    /// Proxy mode.
    pub mode: ProxyMode,
    /// Structure asked for (`wgpu-compute`'s grid; the others have one).
    pub structure: Structure,
    /// Candidate pairs tested (box or cell hits) in one detection.
    pub candidates: u64,
    /// Candidates per sphere (per ray).
    pub candidates_per_sphere: f64,
    /// Colliding pairs found.
    pub pairs: u64,
    /// [`pairs_digest`] of the pairs found (equal digests: equal pairs).
    pub pairs_digest: String,
    /// The clock of `build_ms`, `detect_ms` and `total_ms`: GPU timestamps where every repeat
    /// had them, else wall clock.
    pub clock: Clock,
    /// Build \[ms\].
    pub build_ms: Spread,
    /// Detection (finding and returning every pair) \[ms\].
    pub detect_ms: Spread,
    /// Build + detection \[ms\].
    pub total_ms: Spread,
    /// Build + detection on the host's wall clock \[ms\] (uploads and read-backs included).
    pub wall_total_ms: Spread,
    /// `nns` detection median over this row's (rows in `mochi` mode).
    pub detect_speedup_vs_nns: Option<f64>,
    /// The cpu backend's total median over this row's (same scene, n and mode).
    pub speedup_vs_cpu: Option<f64>,
}

/// One DEM measurement: the same stepper advanced `steps` steps per repeat.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DemRow {
    /// Experiment 2–8.
    pub experiment: Experiment,
    /// The backend.
    #[serde(with = "mochi::names::by_name")]
    pub backend: BackendKind,
    /// Its device, in words.
    pub device: String,
    /// The scene (`freefall`, `rotating`, `slab`, `polylog`).
    pub scene: SceneKind,
    /// Spheres.
    pub n: usize,
    /// Proxy mode.
    pub mode: ProxyMode,
    /// Structure asked for (`wgpu-compute`'s grid).
    pub structure: Structure,
    /// Rebuild policy: `auto`, an interval in steps, or `every step` for steps that never refit.
    pub rebuild: String,
    /// Whether the step refits between rebuilds.
    pub refits: bool,
    /// Timed steps per repeat.
    pub steps: u32,
    /// Time step \[s\] (`None` in reports older than schema 2).
    #[serde(default)]
    pub dt: Option<f64>,
    /// Untimed steps the start state had run before this row's runs began (the slab's settling,
    /// the pile's pouring; 0: the scene's start at t = 0).
    #[serde(default)]
    pub settled: u64,
    /// The steps timed, counted from the scene's start (`None` in reports older than schema 2).
    #[serde(default)]
    pub timed: Option<StepRange>,
    /// Touching pairs in the last step of the last timed run (experiment 8: at the end of the
    /// drop).
    pub contacts: u64,
    /// The clock of the times.
    pub clock: Clock,
    /// Structure maintenance per step \[ms\].
    pub build_ms: Spread,
    /// Detection with contact forces per step \[ms\].
    pub dcd_ms: Spread,
    /// Walls, gravity, integration per step \[ms\].
    pub update_ms: Spread,
    /// The whole step \[ms\].
    pub total_ms: Spread,
    /// The whole step on the host's wall clock \[ms\], submissions and read-backs included
    /// (the only time of a GPU without timestamps).
    pub wall_ms: Spread,
    /// The cpu backend's total median over this row's (same experiment, scene, box, n, mode;
    /// the cpu step never refits, so its one row serves every rebuild policy).
    pub speedup_vs_cpu: Option<f64>,
    /// The contact history after the timed steps (experiment 7; `None` for steps that keep
    /// none).
    #[serde(default)]
    pub history: Option<HistorySize>,
    /// The scene's box per side over its own (experiment 8's wide box; `None`: its own box).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub box_scale: Option<u32>,
    /// The grid build the step chose (`dense` or `sorted`; `None` for backends without one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid_build: Option<String>,
}

/// The steps a DEM row timed, counted from its scene's start (t = 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct StepRange {
    /// First step timed.
    pub from: u64,
    /// One past the last step timed.
    pub to: u64,
    /// Whether every run timed `from..to` again from the same start (experiment 8's drop);
    /// else the runs followed one another, each timing its share of `from..to`.
    pub each_run: bool,
}

impl std::fmt::Display for StepRange {
    /// "0–5000 (every run from the start)" or "3020–3120".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}–{}", self.from, self.to)?;
        if self.each_run {
            write!(f, " (every run from the start)")?;
        }
        Ok(())
    }
}

impl DemRow {
    /// The row's time step, steps and contacts in words: "dt 1e-4, timed steps 17000–17020, after
    /// 17,000 steps settling or pouring, 1,090,000 contacts at the end".
    pub fn state(&self) -> String {
        let r = self;
        let mut words = Vec::new();
        if let Some(dt) = r.dt {
            words.push(format!("dt {}", significant(dt, 4)));
        }
        if let Some(t) = r.timed {
            let before = match r.settled {
                0 => String::new(),
                s => format!(", after {} steps settling or pouring", thousands(s)),
            };
            words.push(format!("timed steps {t}{before}"));
        }
        words.push(format!("{} contacts at the end", thousands(r.contacts)));
        words.join(", ")
    }

    /// The scene and, where they vary, its box and the grid build, in words ("mesh, box ×10,
    /// sorted build").
    pub fn setup(&self) -> String {
        let mut words = vec![self.scene.to_string()];
        if let Some(scale) = self.box_scale {
            words.push(format!("box ×{scale}"));
        }
        if let Some(build) = &self.grid_build {
            words.push(format!("{build} build"));
        }
        words.join(", ")
    }
}

/// What the contact history of a frictional step holds, and its size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HistorySize {
    /// Contacts held, each pair once per sphere and each wall contact once.
    pub entries: u64,
    /// Slots per sphere (K, grown to the most contacts any sphere needed).
    pub slots: usize,
    /// Bytes per sphere of the per-sphere slots: K entries and a count.
    pub bytes_per_sphere: usize,
}

impl HistorySize {
    /// What `history` holds, and its bytes per sphere in the layout of
    /// [`ContactHistory`](mochi::dem::ContactHistory) (an engine's own copy may differ).
    pub fn of(history: &mochi::dem::ContactHistory) -> Self {
        let entry = std::mem::size_of::<mochi::dem::HistoryEntry>();
        Self {
            entries: history.len() as u64,
            slots: history.slots(),
            bytes_per_sphere: history.slots() * entry + std::mem::size_of::<u32>(),
        }
    }
}

/// A measurement a backend could not make.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Skipped {
    /// The experiment.
    pub experiment: Experiment,
    /// The backend.
    #[serde(with = "mochi::names::by_name")]
    pub backend: BackendKind,
    /// What was to be measured.
    pub what: String,
    /// Why it was not.
    pub reason: String,
}

impl Report {
    /// Fills in the speed-ups (mochi vs nns, backend vs cpu) from the medians of the rows.
    pub fn fill_speedups(&mut self) {
        let detect = self.detect.clone();
        for row in &mut self.detect {
            let peer = |backend: BackendKind, mode: ProxyMode| {
                detect.iter().find(|o| {
                    o.backend == backend && o.mode == mode && o.scene == row.scene && o.n == row.n
                })
            };
            row.detect_speedup_vs_nns = (row.mode == ProxyMode::Mochi)
                .then(|| peer(row.backend, ProxyMode::Nns))
                .flatten()
                .map(|nns| ratio(nns.detect_ms.median, row.detect_ms.median));
            row.speedup_vs_cpu = peer(BackendKind::Cpu, row.mode)
                .filter(|_| row.backend != BackendKind::Cpu)
                .map(|cpu| ratio(cpu.total_ms.median, row.total_ms.median));
        }
        let dem = self.dem.clone();
        for row in &mut self.dem {
            row.speedup_vs_cpu = dem
                .iter()
                .find(|o| {
                    o.backend == BackendKind::Cpu
                        && o.experiment == row.experiment
                        && o.scene == row.scene
                        && o.n == row.n
                        && o.mode == row.mode
                        && o.box_scale == row.box_scale
                        && (o.rebuild == row.rebuild || !o.refits)
                })
                .filter(|_| row.backend != BackendKind::Cpu)
                .map(|cpu| ratio(cpu.total_ms.median, row.total_ms.median));
        }
    }
}

/// `x` with thousands separated by commas.
pub fn thousands(x: u64) -> String {
    let digits = x.to_string();
    let mut out = String::new();
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// `a / b`, or infinity when `b` is not positive.
fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 { a / b } else { f64::INFINITY }
}

/// FNV-1a (64-bit) of the pairs in sorted order, as 16 hex digits: equal pair sets, equal
/// digests, whatever order a backend returns them in.
pub fn pairs_digest(pairs: &[mochi::Pair]) -> String {
    let mut sorted = pairs.to_vec();
    sorted.sort_unstable();
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for p in &sorted {
        for byte in p.i.to_le_bytes().into_iter().chain(p.j.to_le_bytes()) {
            h ^= byte as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    format!("{h:016x}")
}

/// Now, UTC, as `YYYY-MM-DDTHH:MM:SSZ`.
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rest) = (secs / 86_400, secs % 86_400);
    let (y, m, d) = civil_from_days(days as i64);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rest / 3600,
        rest / 60 % 60,
        rest % 60
    )
}

/// Year, month and day of the `days`-th day after 1970-01-01 (H. Hinnant's algorithm).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// One target and how the report meets it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Check {
    /// The target, in words.
    pub target: String,
    /// What was measured (backend, value, size, contacts).
    pub measured: String,
    /// Met, missed, or `None` where it was not judged.
    pub met: Option<bool>,
    /// Why it was not judged, where the report measured something it could not judge (a state
    /// without contacts, another size or workload).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_judged: Option<String>,
}

/// One figure of another code.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PeerFigure {
    /// The experiment whose rows it is compared with (a DEM experiment).
    pub experiment: Experiment,
    /// The scene of the rows compared (`None`: every row of the experiment).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<SceneKind>,
    /// The other code.
    pub peer: String,
    /// Its time per step \[ms\].
    pub ms_per_step: f64,
    /// What it ran, in words.
    pub workload: String,
    /// Its spheres (`None`: not said; then the ratio is printed for any size, and says so).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spheres: Option<usize>,
    /// Its contacts at the end.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contacts: Option<u64>,
    /// Its device.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
    /// When it was measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub date: Option<String>,
    /// The other code's version or commit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub commit: Option<String>,
}

/// A figure of another code beside mochi's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    /// The other code's figure, as read.
    pub peer: PeerFigure,
    /// mochi's row compared (backend, setup, n, time step, steps timed, contacts), or why there
    /// is none.
    pub mochi: String,
    /// mochi's time per step \[ms\] (the row's median), where a row was found.
    pub mochi_ms_per_step: Option<f64>,
    /// The other code's time over mochi's, where both measured the same size (or the peer did
    /// not say its size).
    pub mochi_faster: Option<f64>,
    /// Why there is no ratio, or what to keep in mind reading it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn civil_dates() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(20_779), (2026, 11, 22));
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
    }

    #[test]
    fn the_digest_depends_on_every_pair() {
        let a = [mochi::Pair::new(0, 1), mochi::Pair::new(2, 5)];
        let b = [mochi::Pair::new(0, 1), mochi::Pair::new(2, 6)];
        assert_ne!(pairs_digest(&a), pairs_digest(&b));
        assert_eq!(pairs_digest(&a), pairs_digest(&[a[1], a[0]]));
    }
}
