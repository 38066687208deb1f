//! CSV logs a run appends rows to as it goes (`walls.csv`, `flow.csv`): started with a header,
//! or on a resume cut back to the whole rows up to the resume's time (the first column), then
//! appended to. Each append is one write of whole rows at the end of the file, so a frame costs
//! its own rows, never the whole log; a resume drops a row a killed run left without its end.

use super::{io_error, write_atomically};
use crate::error::Result;

/// File name of a run's inflow and outflow counts.
pub const FLOW_LOG: &str = "flow.csv";

/// Header of [`FLOW_LOG`]: per frame the spheres present, and those inserted, refused and
/// removed, and the mass removed \[kg\], since the previous row (on a resume, since the resume).
pub const FLOW_LOG_HEADER: &str = "time,spheres,inserted,refused,removed,removed_mass";

/// Starts the log `path` with `header`, or on a resume (`resume_time` given) keeps its rows
/// of times up to it instead (a log that is not there starts anew).
pub fn start_log(path: &std::path::Path, header: &str, resume_time: Option<f64>) -> Result<()> {
    let kept: String = match resume_time {
        Some(t) if path.exists() => {
            let text = std::fs::read_to_string(path).map_err(io_error(path))?;
            text.split_inclusive('\n')
                .skip(1)
                .filter_map(|line| line.strip_suffix('\n'))
                .filter(|line| {
                    let time = line.split(',').next().and_then(|x| x.parse::<f64>().ok());
                    time.is_some_and(|x| x <= t)
                })
                .map(|line| format!("{line}\n"))
                .collect()
        }
        _ => String::new(),
    };
    write_atomically(path, |out| {
        writeln!(out, "{header}")?;
        out.write_all(kept.as_bytes())
    })
}

/// Appends `lines` (each ending in a newline) to the log `path`, which [`start_log`] started.
pub fn append_log(path: &std::path::Path, lines: &str) -> Result<()> {
    use std::io::Write;
    std::fs::File::options()
        .append(true)
        .open(path)
        .and_then(|mut file| file.write_all(lines.as_bytes()))
        .map_err(io_error(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_are_appended_and_a_resume_keeps_the_rows_up_to_its_time() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.csv");
        start_log(&path, "time,x", None).unwrap();
        append_log(&path, "0e0,1\n").unwrap();
        append_log(&path, "1e-1,2\n2e-1,3\n").unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "time,x\n0e0,1\n1e-1,2\n2e-1,3\n");
        start_log(&path, "time,x", Some(0.1)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "time,x\n0e0,1\n1e-1,2\n");
        // A row a killed run left without its end is dropped.
        append_log(&path, "2e-1,3\n3e-1,").unwrap();
        start_log(&path, "time,x", Some(1.0)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, "time,x\n0e0,1\n1e-1,2\n2e-1,3\n");
        start_log(&path, "time,x", None).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "time,x\n");
    }
}
