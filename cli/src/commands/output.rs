//! Where the commands write: checks made before anything is written or computed (no output names
//! an input, every output's folder exists) and the claim on a simulation's output folder.

use anyhow::{Result, bail};
use mochi::io::{self, RunFolder};
use std::path::{Component, Path, PathBuf};

/// The folder a file is in (`.` for a bare name).
pub fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Refuses an output (`option` names it) that is the file `input`, under any name or link.
pub fn refuse_same_file(input: &Path, output: &Path, option: &str) -> Result<()> {
    if io::same_file(input, output) {
        bail!(
            "{option} {} is the input file {}: writing it would destroy the input; choose another \
             output",
            output.display(),
            input.display()
        );
    }
    Ok(())
}

/// Whether `a` and `b` spell the same path, but for `.` components.
fn same_spelling(a: &Path, b: &Path) -> bool {
    let plain = |p| Path::components(p).filter(|c| *c != Component::CurDir);
    plain(a).eq(plain(b))
}

/// Refuses an output file (`option` names it) whose folder does not exist (and is not `created`,
/// a folder the command creates before it writes there), before any work is done.
pub fn check_output_folder(path: &Path, option: &str, created: Option<&Path>) -> Result<()> {
    let folder = folder_of(path);
    if created.is_some_and(|c| same_spelling(c, folder)) {
        return Ok(());
    }
    match std::fs::metadata(folder) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => bail!(
            "{option} {}: {} is not a folder",
            path.display(),
            folder.display()
        ),
        Err(e) => bail!(
            "{option} {}: the folder {} does not exist: {e}",
            path.display(),
            folder.display()
        ),
    }
}

/// Refuses a simulation whose output folder `out` would take the place of one of its `inputs`
/// (a sphere file, mesh or scene file that is a run file there) or of the `gif`.
pub fn check_run_outputs(out: &Path, inputs: &[&Path], gif: Option<&Path>) -> Result<()> {
    for input in inputs {
        if io::is_run_file_of(input, out) {
            bail!(
                "{} lies in the output folder {} and has the name of a file the run writes there: \
                 copy it elsewhere or choose another folder with -o",
                input.display(),
                out.display()
            );
        }
    }
    if let Some(gif) = gif {
        for input in inputs {
            refuse_same_file(input, gif, "--gif")?;
        }
        if gif
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(io::is_run_file_name)
            && (same_spelling(folder_of(gif), out) || io::same_file(folder_of(gif), out))
        {
            bail!(
                "--gif {} has the name of a file the run writes into {}: choose another name",
                gif.display(),
                out.display()
            );
        }
    }
    Ok(())
}

/// Refuses an output of `mochi render` (`option` names it) that would take the place of a file
/// of the run in `run_dir` or of one of `inputs` (under any name or link): a run file there (a
/// frame's picture, `frame_<step>.png`, only where `picture` says the output is one), or a
/// file with a run file's name anywhere.
pub fn check_render_output(
    output: &Path,
    option: &str,
    run_dir: &Path,
    inputs: &[PathBuf],
    picture: bool,
) -> Result<()> {
    for input in inputs {
        refuse_same_file(input, output, option)?;
    }
    let name = output.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let is_picture = picture && name.starts_with("frame_") && name.ends_with(".png");
    if io::is_run_file_name(name) && !is_picture {
        let in_run =
            same_spelling(folder_of(output), run_dir) || io::same_file(folder_of(output), run_dir);
        if in_run || output.exists() {
            bail!(
                "{option} {} would replace a file of a simulation run ({name} is a name `mochi \
                 simulate` writes): choose another name",
                output.display()
            );
        }
    }
    Ok(())
}

/// Refuses the folder `out` when it holds the files of an earlier run.
pub fn refuse_earlier_run(out: &Path) -> Result<()> {
    let earlier = io::run_files_in(out)?;
    if earlier.is_empty() {
        return Ok(());
    }
    let names: Vec<String> = earlier
        .iter()
        .take(3)
        .filter_map(|f| f.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .collect();
    let more = match earlier.len() - names.len() {
        0 => String::new(),
        n => format!(" and {n} more"),
    };
    bail!(
        "{} holds an earlier run ({}{more}): --overwrite replaces it, --resume {} continues it, \
         or choose another folder with -o",
        out.display(),
        names.join(", "),
        out.join(io::CHECKPOINT_FILE).display()
    );
}

/// Locks the simulation folder `out` (created if needed) for this run. A folder that holds the
/// files of an earlier run is refused, unless the run resumes it (`resume`), or `overwrite`:
/// then those files (and only those) are removed first.
pub fn claim_run_folder(out: &Path, resume: bool, overwrite: bool) -> Result<RunFolder> {
    let folder = RunFolder::lock(out)?;
    if overwrite {
        folder.clear()?;
    } else if !resume {
        refuse_earlier_run(out)?;
    }
    Ok(folder)
}
