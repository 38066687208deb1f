//! The options of one backend (`--structure`, `--grid-build`, `--rebuild`), as the command line
//! gives them: an option the backend that runs does not use is an error where the backend was
//! named, and a warning where `auto` picked it.

use anyhow::{Result, bail};
use mochi::engines::wgpu::compute::{GridBuild, Structure};
use mochi::engines::{BackendChoice, BackendKind, Options, RebuildPolicy};

/// The backend options given (`None`: not given, the default applies).
#[derive(Debug, Clone, Copy, Default)]
pub struct BackendFlags {
    /// `--structure`.
    pub structure: Option<Structure>,
    /// `--grid-build`.
    pub grid_build: Option<GridBuild>,
    /// `--rebuild`.
    pub rebuild: Option<RebuildPolicy>,
}

impl BackendFlags {
    /// The options, defaults filled in.
    pub fn options(&self) -> Options {
        Options {
            structure: self.structure.unwrap_or_default(),
            grid_build: self.grid_build.unwrap_or_default(),
            rebuild: self.rebuild.unwrap_or_default(),
        }
    }

    /// The options given that `kind` does not use, as flags, with the backend that does.
    fn unused_by(&self, kind: BackendKind) -> Vec<(&'static str, BackendKind)> {
        let given = [
            (
                "--structure",
                self.structure.is_some(),
                BackendKind::WgpuCompute,
            ),
            (
                "--grid-build",
                self.grid_build.is_some(),
                BackendKind::WgpuCompute,
            ),
            ("--rebuild", self.rebuild.is_some(), BackendKind::Optix),
        ];
        given
            .into_iter()
            .filter(|&(_, given, user)| given && user != kind)
            .map(|(flag, _, user)| (flag, user))
            .collect()
    }

    /// Refuses options a named backend does not use (`auto` is checked once it has picked,
    /// by [`Self::warning`]).
    pub fn check(&self, choice: BackendChoice) -> Result<()> {
        if let BackendChoice::Named(kind) = choice
            && let Some((flag, user)) = self.unused_by(kind).first()
        {
            bail!(
                "{flag} is an option of the {} backend; --backend {} does not use it",
                user.name(),
                kind.name()
            );
        }
        Ok(())
    }

    /// The warning for options the backend `auto` picked (`kind`) does not use, if any.
    pub fn warning(&self, choice: BackendChoice, kind: BackendKind) -> Option<String> {
        let unused = self.unused_by(kind);
        (choice == BackendChoice::Auto && !unused.is_empty()).then(|| {
            let flags: Vec<String> = (unused.iter())
                .map(|(flag, user)| format!("{flag} (an option of {})", user.name()))
                .collect();
            format!(
                "auto picked the {} backend, which does not use {}",
                kind.name(),
                flags.join(", ")
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_option_a_backend_does_not_use_is_an_error_when_named_and_a_warning_with_auto() {
        let flags = BackendFlags {
            structure: Some(Structure::Mlgrid),
            rebuild: Some(RebuildPolicy::Every(5)),
            ..BackendFlags::default()
        };
        let cpu = BackendChoice::Named(BackendKind::Cpu);
        let e = flags.check(cpu).unwrap_err().to_string();
        assert!(
            e.contains("--structure is an option of the wgpu-compute backend"),
            "{e}"
        );
        let compute = BackendChoice::Named(BackendKind::WgpuCompute);
        let e = flags.check(compute).unwrap_err().to_string();
        assert!(
            e.contains("--rebuild is an option of the optix backend"),
            "{e}"
        );
        assert!(BackendFlags::default().check(cpu).is_ok());
        let warning = flags
            .warning(BackendChoice::Auto, BackendKind::Cpu)
            .unwrap();
        assert!(
            warning.contains("--structure") && warning.contains("--rebuild"),
            "{warning}"
        );
        assert_eq!(flags.warning(cpu, BackendKind::Cpu), None);
        assert_eq!(flags.options().rebuild, RebuildPolicy::Every(5));
    }
}
