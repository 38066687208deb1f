//! The report as Markdown: a header (date, command, machine, backends) and one table per
//! experiment.

use super::plan::DROP_STEPS;
use super::plan::Experiment;
use super::report::{DemRow, DetectRow, Report};
use super::stats::Spread;
use mochi::dem::Clock;
use mochi::numbers::significant;
use std::fmt::Write;

/// The whole report as Markdown.
pub fn render(report: &Report) -> String {
    let mut out = String::new();
    header(&mut out, report);
    for &experiment in &report.settings.experiments {
        let _ = writeln!(
            out,
            "\n## {}. {}\n\nWorkload: {}\n",
            experiment.number(),
            experiment.title(),
            experiment.workload(&report.settings)
        );
        if experiment == Experiment::Dcd {
            detect_table(&mut out, &report.detect);
        } else {
            let rows: Vec<&DemRow> = report
                .dem
                .iter()
                .filter(|r| r.experiment == experiment)
                .collect();
            dem_table(&mut out, &rows, experiment == Experiment::Rebuild);
            if experiment == Experiment::Friction {
                history_table(&mut out, &rows);
            }
        }
    }
    if !report.targets.is_empty() {
        out.push_str(
            "\n## Performance targets\n\n| target | measured | met |\n| --- | --- | --- |\n",
        );
        for t in &report.targets {
            let met = match (t.met, &t.not_judged) {
                (Some(true), _) => "yes",
                (Some(false), _) => "**no**",
                (None, Some(why)) => why.as_str(),
                (None, None) => "–",
            };
            let _ = writeln!(out, "| {} | {} | {met} |", t.target, t.measured);
        }
    }
    if !report.comparisons.is_empty() {
        out.push_str(
            "\n## Against other codes (--compare)\n\n| experiment | other code | its workload | \
             its device, date | its ms/step | mochi's row | mochi ms/step | mochi faster |\n\
             | --- | --- | --- | --- | --- | --- | --- | --- |\n",
        );
        for c in &report.comparisons {
            let p = &c.peer;
            let mut workload = p.workload.clone();
            if let Some(n) = p.spheres {
                let _ = write!(workload, "; {n} spheres");
            }
            if let Some(contacts) = p.contacts {
                let _ = write!(workload, "; {contacts} contacts");
            }
            let when = [p.device.as_deref(), p.date.as_deref(), p.commit.as_deref()]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>()
                .join(", ");
            let faster = match (c.mochi_faster, &c.note) {
                (Some(x), Some(note)) => format!("{x:.2}× ({note})"),
                (Some(x), None) => format!("{x:.2}×"),
                (None, Some(note)) => note.clone(),
                (None, None) => "–".to_owned(),
            };
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                p.experiment.number(),
                cell(&p.peer),
                cell(&workload),
                if when.is_empty() {
                    "–".to_owned()
                } else {
                    cell(&when)
                },
                time(p.ms_per_step),
                cell(&c.mochi),
                c.mochi_ms_per_step.map_or_else(|| "–".to_owned(), time),
                cell(&faster),
            );
        }
    }
    if !report.skipped.is_empty() {
        out.push_str("\n## Not measured\n\n| experiment | backend | what | why |\n| --- | --- | --- | --- |\n");
        for s in &report.skipped {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {} |",
                s.experiment.number(),
                s.backend.name(),
                s.what,
                s.reason.replace('|', "/")
            );
        }
    }
    out
}

fn header(out: &mut String, r: &Report) {
    let s = &r.settings;
    let m = &r.machine;
    let _ = writeln!(out, "# mochi bench\n");
    let _ = writeln!(out, "- date: {} (mochi {})", r.date, r.mochi_version);
    let _ = writeln!(out, "- command: `{}`", r.command);
    let _ = writeln!(
        out,
        "- machine: {} {}, {}, {} threads",
        m.os,
        m.arch,
        m.cpu.as_deref().unwrap_or("unknown CPU"),
        m.threads
    );
    for b in &r.backends {
        match (&b.device, &b.left_out) {
            (_, Some(why)) => {
                let _ = writeln!(out, "- {}: left out ({why})", b.name.name());
            }
            (Some(device), None) => {
                let _ = writeln!(out, "- {}: {device}", b.name.name());
            }
            (None, None) => {
                let _ = writeln!(out, "- {}", b.name.name());
            }
        }
    }
    let _ = writeln!(
        out,
        "\nTimes: median (min–max) of {} timed runs after {} warm-up runs, in ms; the clock column \
         says whether they are GPU timestamps or wall clock. DEM rows: per step, {} steps per run \
         (experiment 8: the whole drop, {} steps, every run from the start); each row says its \
         time step, the steps it timed (counted from the scene's start) and the contacts in its \
         last step.",
        s.repeats, s.warmup, s.steps, DROP_STEPS
    );
}

fn detect_table(out: &mut String, rows: &[DetectRow]) {
    if rows.is_empty() {
        out.push_str("No rows (see \"Not measured\").\n");
        return;
    }
    out.push_str(
        "| backend | scene | n | mode | structure | candidates/sphere | pairs | build | detect | \
         build + detect | clock | mochi vs nns (detect) | vs cpu |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.2} | {} | {} | {} | {} | {} | {} | {} |",
            r.backend.name(),
            r.scene,
            r.n,
            r.mode.name(),
            r.structure.name(),
            r.candidates_per_sphere,
            r.pairs,
            spread(&r.build_ms),
            spread(&r.detect_ms),
            spread(&r.total_ms),
            clock(r.clock),
            speedup(r.detect_speedup_vs_nns),
            speedup(r.speedup_vs_cpu),
        );
    }
}

fn dem_table(out: &mut String, rows: &[&DemRow], with_rebuild: bool) {
    if rows.is_empty() {
        out.push_str("No rows (see \"Not measured\").\n");
        return;
    }
    let rebuild_head = if with_rebuild { " rebuild |" } else { "" };
    let rebuild_rule = if with_rebuild { " --- |" } else { "" };
    let _ = writeln!(
        out,
        "| backend | scene | n | mode | structure |{rebuild_head} dt [s] | steps timed | contacts \
         (last step) | build | DCD | update | total [ms/step] | clock | wall [ms/step] | vs cpu |\n\
         | --- | --- | --- | --- | --- |{rebuild_rule} --- | --- | --- | --- | --- | --- | --- | --- \
         | --- | --- |"
    );
    for r in rows {
        let rebuild = if with_rebuild {
            format!(" {} |", r.rebuild)
        } else {
            String::new()
        };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} |{rebuild} {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.backend.name(),
            r.setup(),
            r.n,
            r.mode.name(),
            r.structure.name(),
            r.dt.map_or_else(|| "–".to_owned(), |dt| significant(dt, 4)),
            r.timed.map_or_else(
                || "–".to_owned(),
                |t| match r.settled {
                    0 => t.to_string(),
                    s => format!("{t} (after {s} settling or pouring)"),
                }
            ),
            r.contacts,
            spread(&r.build_ms),
            spread(&r.dcd_ms),
            spread(&r.update_ms),
            spread(&r.total_ms),
            clock(r.clock),
            spread(&r.wall_ms),
            speedup(r.speedup_vs_cpu),
        );
    }
}

/// The contact history of the rows that keep one (experiment 7), as read back: the cpu's layout,
/// each pair on both sides (a GPU keeps each pair once; its own size is in its description).
fn history_table(out: &mut String, rows: &[&DemRow]) {
    let kept: Vec<_> = rows
        .iter()
        .filter_map(|r| r.history.map(|h| (r, h)))
        .collect();
    if kept.is_empty() {
        return;
    }
    out.push_str(
        "\n| backend | n | contacts (pairs) | held in history (both sides) | slots per sphere \
         (read back) | history read back [bytes/sphere] |\n| --- | --- | --- | --- | --- | --- |\n",
    );
    for (r, h) in kept {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} |",
            r.backend.name(),
            r.n,
            r.contacts,
            h.entries,
            h.slots,
            h.bytes_per_sphere
        );
    }
}

/// `text` for a table cell (no column breaks).
fn cell(text: &str) -> String {
    text.replace('|', "/").replace('\n', " ")
}

/// A time with about three significant digits.
pub fn time(ms: f64) -> String {
    let places = decimals(ms);
    format!("{ms:.places$}")
}

/// Decimal places that give `ms` about three significant digits.
fn decimals(ms: f64) -> usize {
    match ms.abs() {
        t if t >= 100.0 => 0,
        t if t >= 10.0 => 1,
        t if t >= 1.0 => 2,
        _ => 3,
    }
}

/// Median (min–max), all three to the median's decimal places.
fn spread(s: &Spread) -> String {
    let p = decimals(s.median);
    format!("{:.p$} ({:.p$}–{:.p$})", s.median, s.min, s.max)
}

fn clock(c: Clock) -> &'static str {
    match c {
        Clock::Gpu => "GPU",
        Clock::Wall => "wall",
        Clock::None => "none",
    }
}

/// A speed-up as `3.2×`, or `–`.
pub fn speedup(s: Option<f64>) -> String {
    s.map_or_else(|| "–".to_owned(), |x| format!("{x:.2}×"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::targets::{NO_CONTACTS, check, tests::report};

    #[test]
    fn a_target_not_judged_prints_why_and_is_not_met() {
        let mut r = report(3000);
        for row in &mut r.dem {
            row.contacts = 0;
        }
        let md = render(&Report {
            targets: check(&r),
            ..r
        });
        assert!(md.contains(&format!("| {NO_CONTACTS} |")), "{md}");
        assert!(!md.contains("| yes |"), "{md}");
    }
}
