//! The report drawn as SVG, like the paper's figures: bars per phase per backend with speed-up
//! labels, mochi-vs-nns bars per radius ratio, time against the rebuild interval, and log–log
//! scaling curves. SVG text needs no font files.

use super::markdown::{speedup, time};
use super::plan::Experiment;
use super::report::{DemRow, Report};
use anyhow::{Result, anyhow};
use mochi::proxy::ProxyMode;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

type Drawn = std::result::Result<(), Box<dyn std::error::Error>>;

/// Size of a plot \[px\]; bar charts widen to give each group [`GROUP_WIDTH`].
const SIZE: (u32, u32) = (1000, 560);
/// Width of one group of bars \[px\].
const GROUP_WIDTH: u32 = 170;
/// Height of a line of label text \[px\].
const LINE: i32 = 15;
const FONT: &str = "sans-serif";
/// Colours of the phases (build, DCD/detect, update) and of the legend keys of bar charts.
const KEYS: [RGBColor; 3] = [
    RGBColor(66, 114, 196),
    RGBColor(237, 125, 49),
    RGBColor(112, 173, 71),
];

/// Every plot the report has rows for, as (file name, SVG text).
pub fn draw(report: &Report) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for &experiment in &report.settings.experiments {
        let rows: Vec<&DemRow> = report
            .dem
            .iter()
            .filter(|r| r.experiment == experiment)
            .collect();
        let name = format!("{}.svg", experiment.name());
        let title = format!("{}. {}", experiment.number(), experiment.title());
        let svg = match experiment {
            Experiment::Dcd if !report.detect.is_empty() => {
                let width = bar_chart_width(report.detect.len() / 2);
                svg(&name, width, |a| dcd(a, &title, report))
            }
            Experiment::Freefall
            | Experiment::Rotating
            | Experiment::Targets
            | Experiment::Friction
            | Experiment::Clustered
                if !rows.is_empty() =>
            {
                svg(&name, bar_chart_width(rows.len()), |a| {
                    phases(a, &title, &rows)
                })
            }
            Experiment::Rebuild if !rows.is_empty() => {
                svg(&name, SIZE.0, |a| rebuild(a, &title, &rows))
            }
            Experiment::Scaling if !rows.is_empty() => {
                svg(&name, SIZE.0, |a| scaling(a, &title, &rows))
            }
            _ => continue,
        }?;
        out.push((name, svg));
    }
    Ok(out)
}

type Area<'a> = DrawingArea<SVGBackend<'a>, plotters::coord::Shift>;

/// Width of a bar chart of `groups` groups \[px\].
fn bar_chart_width(groups: usize) -> u32 {
    SIZE.0.max(90 + GROUP_WIDTH * groups as u32)
}

/// Runs `draw` on a blank SVG `width` pixels wide and returns its text.
fn svg(name: &str, width: u32, draw: impl FnOnce(&Area) -> Drawn) -> Result<String> {
    let mut text = String::new();
    {
        let area = SVGBackend::with_string(&mut text, (width, SIZE.1)).into_drawing_area();
        let drawn = area
            .fill(&WHITE)
            .map_err(Into::into)
            .and_then(|()| draw(&area))
            .and_then(|()| area.present().map_err(Into::into));
        drawn.map_err(|e| anyhow!("plot {name}: {e}"))?;
    }
    Ok(text)
}

/// One bar: stacked segments (legend key, value) and a label above it (lines split at `\n`).
struct Bar {
    segments: Vec<(usize, f64)>,
    label: String,
}

/// Bars in groups along x, each group named below the axis (lines split at `\n`); `legend`
/// names the keys.
fn bars(area: &Area, title: &str, legend: &[&str], groups: &[(String, Vec<Bar>)]) -> Drawn {
    let top = groups
        .iter()
        .flat_map(|(_, bars)| bars)
        .map(|b| b.segments.iter().map(|s| s.1).sum::<f64>())
        .fold(0.0, f64::max);
    let top = if top > 0.0 { top * 1.3 } else { 1.0 };
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 20))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0f64..groups.len() as f64, 0f64..top)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(0)
        .y_desc("ms")
        .draw()?;
    for (key, name) in legend.iter().enumerate() {
        let color = KEYS[key % KEYS.len()];
        chart
            .draw_series(std::iter::empty::<Rectangle<(f64, f64)>>())?
            .label(*name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], color.filled()));
    }
    for (g, (name, group)) in groups.iter().enumerate() {
        let width = 0.8 / group.len().max(1) as f64;
        for (k, bar) in group.iter().enumerate() {
            let x0 = g as f64 + 0.1 + k as f64 * width;
            let x1 = x0 + width * 0.9;
            let mut y = 0.0;
            for &(key, value) in &bar.segments {
                let color = KEYS[key % KEYS.len()];
                chart.draw_series([Rectangle::new([(x0, y), (x1, y + value)], color.filled())])?;
                y += value;
            }
            let (px, py) = chart.backend_coord(&((x0 + x1) / 2.0, y));
            // The last line sits on the bar, the ones before it above.
            let lines: Vec<&str> = bar.label.lines().collect();
            for (i, line) in lines.iter().enumerate() {
                let up = (lines.len() - 1 - i) as i32 * LINE;
                let style = TextStyle::from((FONT, 12)).pos(Pos::new(HPos::Center, VPos::Bottom));
                area.draw(&Text::new(line.to_string(), (px, py - 2 - up), style))?;
            }
        }
        let (px, py) = chart.backend_coord(&(g as f64 + 0.5, 0.0));
        for (i, line) in name.lines().enumerate() {
            let style = TextStyle::from((FONT, 13)).pos(Pos::new(HPos::Center, VPos::Top));
            area.draw(&Text::new(
                line.to_string(),
                (px, py + 8 + i as i32 * LINE),
                style,
            ))?;
        }
    }
    draw_legend(&mut chart)
}

/// Draws the series labels of `chart` in its upper left corner.
fn draw_legend<'a, CT: CoordTranslate>(chart: &mut ChartContext<'a, SVGBackend<'a>, CT>) -> Drawn {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}

/// Experiment 1: detection time, mochi next to nns, per backend and radius ratio.
fn dcd(area: &Area, title: &str, report: &Report) -> Drawn {
    let mut groups: Vec<(String, Vec<Bar>)> = Vec::new();
    for row in &report.detect {
        let name = format!("{}\n{}", row.backend.name(), row.scene);
        if groups.last().is_none_or(|(g, _)| *g != name) {
            groups.push((name, Vec::new()));
        }
        let key = usize::from(row.mode != ProxyMode::Mochi);
        let mut label = format!("{} ms", time(row.detect_ms.median));
        if let Some(s) = row.detect_speedup_vs_nns {
            label = format!("{}\n{label}", speedup(Some(s)));
        }
        if let Some((_, bars)) = groups.last_mut() {
            bars.push(Bar {
                segments: vec![(key, row.detect_ms.median)],
                label,
            });
        }
    }
    bars(
        area,
        &format!("{title} (detect; label: mochi vs nns)"),
        &[ProxyMode::Mochi.name(), ProxyMode::Nns.name()],
        &groups,
    )
}

/// Experiments 2, 3, 6, 7 and 8: one stacked bar of the phases per backend (and scene, structure).
fn phases(area: &Area, title: &str, rows: &[&DemRow]) -> Drawn {
    let groups: Vec<(String, Vec<Bar>)> = rows
        .iter()
        .map(|r| {
            let mut label = format!("{} ms", time(r.total_ms.median));
            if let Some(s) = r.speedup_vs_cpu {
                label = format!("{} vs cpu\n{label}", speedup(Some(s)));
            }
            let bar = Bar {
                segments: vec![
                    (0, r.build_ms.median),
                    (1, r.dcd_ms.median),
                    (2, r.update_ms.median),
                ],
                label,
            };
            let name = if r.experiment == Experiment::Targets {
                format!(
                    "{}\n{} {} {}",
                    r.backend.name(),
                    r.scene,
                    r.mode.name(),
                    r.structure.name()
                )
            } else if r.experiment == Experiment::Clustered {
                format!("{}\n{}", r.backend.name(), r.setup())
            } else {
                format!("{}\nn={}", r.backend.name(), r.n)
            };
            (name, vec![bar])
        })
        .collect();
    bars(
        area,
        &format!("{title}, ms/step"),
        &["build", "DCD", "update"],
        &groups,
    )
}

/// Lines of (x, y) points on log–log axes, one per series, named in a legend.
fn curves(area: &Area, title: &str, x_desc: &str, series: &[(String, Vec<(f64, f64)>)]) -> Drawn {
    let points = || series.iter().flat_map(|(_, p)| p.iter().copied());
    let span = |f: fn((f64, f64)) -> f64| {
        let (lo, hi) = points()
            .map(f)
            .filter(|v| *v > 0.0)
            .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
        if lo > hi {
            (0.1, 10.0)
        } else {
            // Whole decades, at least one, so that the axes have labelled ticks.
            let lo = 10f64.powf(lo.log10().floor());
            let hi = 10f64.powf(hi.log10().ceil()).max(lo * 10.0);
            (lo, hi)
        }
    };
    let (x, y) = (span(|p| p.0), span(|p| p.1));
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x.0..x.1).log_scale(), (y.0..y.1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc("ms per step")
        .x_label_formatter(&|v| log_label(*v, &[1.0]))
        .y_label_formatter(&|v| log_label(*v, &[1.0, 2.0, 5.0]))
        .draw()?;
    for (i, (name, line)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(line.iter().copied(), color.stroke_width(2)))?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2)));
        chart.draw_series(line.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }
    draw_legend(&mut chart)
}

/// A tick label on a log axis: `v` when its leading digit is one of `mantissas` (1k, 20, 0.5),
/// else nothing, so that the minor ticks stay unlabelled.
fn log_label(v: f64, mantissas: &[f64]) -> String {
    let decade = 10f64.powf(v.log10().floor());
    let lead = v / decade;
    if !mantissas.iter().any(|m| (lead - m).abs() < 1e-6) {
        return String::new();
    }
    match v {
        v if v >= 1e6 => format!("{}M", v / 1e6),
        v if v >= 1e3 => format!("{}k", v / 1e3),
        v => format!("{}", (v * 1e6).round() / 1e6),
    }
}

/// Experiment 4: time per step against the rebuild interval; steps that rebuild every step
/// are flat lines across the swept range.
fn rebuild(area: &Area, title: &str, rows: &[&DemRow]) -> Drawn {
    let swept: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.rebuild.parse::<f64>().ok())
        .collect();
    let (lo, hi) = swept
        .iter()
        .fold((1.0f64, 100.0f64), |(lo, hi), &k| (lo.min(k), hi.max(k)));
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in rows {
        let t = r.total_ms.median;
        let (name, points) = match r.rebuild.parse::<f64>() {
            Ok(k) => (r.backend.name().to_owned(), vec![(k, t)]),
            Err(_) if r.refits => (
                format!("{} (auto)", r.backend.name()),
                vec![(lo, t), (hi, t)],
            ),
            Err(_) => (
                format!("{} (rebuilds every step)", r.backend.name()),
                vec![(lo, t), (hi, t)],
            ),
        };
        match series.iter_mut().find(|(n, _)| *n == name) {
            Some((_, line)) => line.extend(points),
            None => series.push((name, points)),
        }
    }
    curves(area, title, "rebuild interval [steps]", &series)
}

/// Experiment 5: time per step against the number of spheres, one curve per backend.
fn scaling(area: &Area, title: &str, rows: &[&DemRow]) -> Drawn {
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for r in rows {
        let point = (r.n as f64, r.total_ms.median);
        let name = r.backend.name();
        match series.iter_mut().find(|(n, _)| n == name) {
            Some((_, line)) => line.push(point),
            None => series.push((name.to_owned(), vec![point])),
        }
    }
    curves(area, title, "spheres", &series)
}
