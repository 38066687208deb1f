//! The DEM step's schedule: when a step sorts, re-bins or lays the grid out again, how many steps
//! a submission holds, and which set and history parity each step works on.

use super::*;

/// Steps between two re-derivations of the grid layout.
pub const RELAYOUT_EVERY: u64 = 100;

/// Steps a submission holds where a batch the host waits for (the granular step's, which may
/// be redone) is submitted a few steps at a time: the GPU starts on them while the host records
/// the next.
pub(super) const STEPS_A_SUBMISSION: u32 = 10;

/// How the next batch the host waits for is submitted, from the last one's GPU time (`times`,
/// where timestamps are taken) and the host's time recording it: [`STEPS_A_SUBMISSION`] steps
/// at a time where the GPU's work took several times the recording, so that the GPU never
/// waits for a submission and its timestamps stay its own work; in one submission otherwise;
/// a few steps at a time where no timestamps are taken.
pub(super) fn submissions(times: Option<&StageTimes>, recorded_ms: f64) -> Option<u32> {
    match times {
        Some(t) if t.total_ms() <= 4.0 * recorded_ms => None,
        _ => Some(STEPS_A_SUBMISSION),
    }
}

/// Steps from one sorting step to the next where binning steps run between them (the state
/// drifts out of sorted order only as fast as spheres change cells).
pub const SORT_EVERY: u64 = 16;

/// Share of a batch's steps above which re-binning is so frequent that the skin costs more
/// than it saves (its wider windows, and the copy back of each re-binning); the skin is then
/// off for [`SKIN_RETRY_STEPS`] steps (docs/performance-log/2026-11-27-h100-session-6.md has the
/// scenes where the skin loses, docs/performance-log/2026-11-27-h100-session-7.md the share swept
/// with the skin's width).
pub const MAX_REBIN_SHARE: f64 = 0.25;

/// Steps the skin stays off after a batch re-binned too often; then it is tried again.
pub const SKIN_RETRY_STEPS: u64 = 1000;

/// When a step on the dense build moves its state into sorted order (a sorting step); the
/// other steps bin by index. Only speed depends on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sorting {
    /// Every 16 steps (`SORT_EVERY`), as `Every`; where the step has a skin, only after the
    /// state was written out of order (each of its re-binnings sorts).
    Auto,
    /// At the steps whose number is a multiple of `k` (≥ 1), and at the first step after the
    /// state was written out of order (uploaded, spheres appended or removed); where the step
    /// has a skin, those steps re-bin whatever the drift.
    Every(u64),
    /// Never: the state stays in the order given and every step bins by index (where the step
    /// has a skin, it re-bins only where a sphere may have moved the skin).
    Never,
}

/// How a step bins its spheres.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum StepKind {
    /// The state moves into sorted order in the other set, and the step runs there.
    Sorting,
    /// The spheres are binned by index (`home`, `walk_pos`) and the step runs on the state where
    /// it is.
    Binning,
    /// The step with a skin: the state stays on its set in the order of the last binning; where
    /// the step re-bins ([`Rebin`]) it sorts the state into the other set and copies it back.
    Skin,
}

/// Whether a step with a skin re-bins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Rebin {
    /// Whatever the drift: the first step after the host wrote the state or laid the grid out,
    /// a timed batch's first step (whose phases the batch's times are split by), and the steps
    /// [`Sorting`] sorts at.
    Always,
    /// Where some sphere may have moved more than the skin since the last binning.
    IfMoved,
}

/// What decides how the coming steps bin and where they run: a copy of the step's state at
/// the start of a batch ([`GridStepper::schedule`]), so the schedule is a pure function of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Schedule {
    /// The next step's number.
    pub step: u64,
    /// When steps sort.
    pub sorting: Sorting,
    /// Whether the next step must sort (the state was written out of order).
    pub sort_next: bool,
    /// Whether the layout has a skin: steps may skip their binning.
    pub skinned: bool,
    /// Whether the build can bin by index (the dense build): steps between sortings do.
    pub bins_by_index: bool,
    /// Whether the step keeps a contact history, whose two sides alternate step by step.
    pub granular: bool,
}

impl Schedule {
    /// How the step after the next `ahead` steps bins.
    pub fn kind_of_step(&self, ahead: u32) -> StepKind {
        if self.skinned {
            return StepKind::Skin;
        }
        match self.bins_by_index && !self.sorts(ahead) {
            true => StepKind::Binning,
            false => StepKind::Sorting,
        }
    }

    /// Whether the step after the next `ahead` steps sorts (as [`Sorting`] says).
    pub fn sorts(&self, ahead: u32) -> bool {
        let every = match (self.sorting, self.skinned) {
            (Sorting::Auto, false) => Some(SORT_EVERY),
            (Sorting::Auto, true) | (Sorting::Never, _) => None,
            (Sorting::Every(k), _) => Some(k),
        };
        let due = |k: u64| (self.step + ahead as u64).is_multiple_of(k.max(1));
        (self.sort_next && ahead == 0 && every.is_some()) || every.is_some_and(due)
    }

    /// The buffers the step after one of kind `kind` from `turn` starts from: a sorting step
    /// moves the state into the other set (a step with a skin moves it back); the granular
    /// step's history changes sides at every step.
    pub fn turn_after(&self, kind: StepKind, turn: Turn) -> Turn {
        Turn {
            set: match kind {
                StepKind::Sorting => 1 - turn.set,
                StepKind::Binning | StepKind::Skin => turn.set,
            },
            parity: match self.granular {
                true => 1 - turn.parity,
                false => 0,
            },
        }
    }
}

impl GridStepper {
    /// The schedule of the coming steps, from the step's state now.
    pub(super) fn schedule(&self) -> Schedule {
        Schedule {
            step: self.step,
            sorting: self.sorting,
            sort_next: self.sort_next,
            skinned: self.skinned(),
            bins_by_index: self.res.pipelines.bin_index.is_some(),
            granular: self.res.granular.is_some(),
        }
    }

    /// The buffers the next step starts from.
    pub(super) fn turn(&self) -> Turn {
        Turn {
            set: self.current,
            parity: self.parity,
        }
    }

    /// Whether the layout has a skin: steps may skip their binning.
    pub(super) fn skinned(&self) -> bool {
        self.res.pipelines.skin.is_some() && self.laid_out.layout.skin > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_is_split_where_the_gpu_outlasts_its_recording() {
        let gpu_ms = |total: f64| StageTimes {
            build_ms: total / 2.0,
            dcd_ms: total / 4.0,
            update_ms: total / 4.0,
        };
        assert_eq!(
            submissions(Some(&gpu_ms(32.0)), 3.0),
            Some(STEPS_A_SUBMISSION)
        );
        assert_eq!(submissions(Some(&gpu_ms(2.0)), 3.0), None);
        assert_eq!(submissions(Some(&gpu_ms(12.0)), 3.0), None);
        assert_eq!(submissions(None, 3.0), Some(STEPS_A_SUBMISSION));
    }

    /// The paper's step on the dense build at step 30, no skin, sorting as `sorting` says.
    fn dense(sorting: Sorting) -> Schedule {
        Schedule {
            step: 30,
            sorting,
            sort_next: false,
            skinned: false,
            bins_by_index: true,
            granular: false,
        }
    }

    /// The kinds of the next `n` steps.
    fn kinds(s: &Schedule, n: u32) -> Vec<StepKind> {
        (0..n).map(|ahead| s.kind_of_step(ahead)).collect()
    }

    #[test]
    fn the_dense_build_sorts_every_sort_every_steps_and_bins_by_index_between() {
        let s = dense(Sorting::Auto);
        let sorting: Vec<u32> = (0..40).filter(|&a| s.sorts(a)).collect();
        assert_eq!(sorting, [2, 18, 34], "steps 32, 48 and 64");
        let k = kinds(&s, 4);
        assert_eq!(
            k,
            [
                StepKind::Binning,
                StepKind::Binning,
                StepKind::Sorting,
                StepKind::Binning
            ]
        );
        // The state written out of order: the next step sorts, the ones after as before.
        let written = Schedule {
            sort_next: true,
            ..s
        };
        assert_eq!(kinds(&written, 2), [StepKind::Sorting, StepKind::Binning]);
        let every = dense(Sorting::Every(5));
        assert!((0..10).all(|a| every.sorts(a) == ((30 + a) % 5 == 0)));
        assert_eq!(
            dense(Sorting::Every(0)).kind_of_step(7),
            StepKind::Sorting,
            "k of 0 is 1"
        );
        let never = Schedule {
            sort_next: true,
            ..dense(Sorting::Never)
        };
        assert!((0..40).all(|a| never.kind_of_step(a) == StepKind::Binning));
    }

    #[test]
    fn the_sorted_build_sorts_every_step_and_a_skin_skips_what_it_can() {
        let sorted = Schedule {
            bins_by_index: false,
            ..dense(Sorting::Auto)
        };
        assert!(kinds(&sorted, 20).iter().all(|&k| k == StepKind::Sorting));
        let skin = Schedule {
            skinned: true,
            ..dense(Sorting::Auto)
        };
        assert!(kinds(&skin, 20).iter().all(|&k| k == StepKind::Skin));
        // With a skin, `auto` never sorts on schedule: a batch's first step re-bins where the
        // state was written (`encode_steps`), the others where a sphere may have moved the skin.
        let written = Schedule {
            sort_next: true,
            ..skin
        };
        assert!((0..40).all(|a| !skin.sorts(a) && !written.sorts(a)));
        let every = Schedule {
            sorting: Sorting::Every(4),
            ..skin
        };
        assert_eq!(
            (0..8).filter(|&a| every.sorts(a)).collect::<Vec<_>>(),
            [2, 6]
        );
    }

    #[test]
    fn sorting_moves_the_state_to_the_other_set_and_history_alternates_in_the_granular_step() {
        let start = Turn { set: 0, parity: 1 };
        let paper = dense(Sorting::Auto);
        let granular = Schedule {
            granular: true,
            ..paper
        };
        let after = |s: &Schedule, kind| {
            let t = s.turn_after(kind, start);
            (t.set, t.parity)
        };
        assert_eq!(after(&paper, StepKind::Sorting), (1, 0));
        assert_eq!(after(&paper, StepKind::Binning), (0, 0));
        assert_eq!(after(&paper, StepKind::Skin), (0, 0));
        assert_eq!(after(&granular, StepKind::Sorting), (1, 0));
        assert_eq!(after(&granular, StepKind::Binning), (0, 0));
        let back = granular.turn_after(StepKind::Sorting, Turn { set: 1, parity: 0 });
        assert_eq!((back.set, back.parity), (0, 1));
    }
}
