//! The machine file over the API: read by anyone, written by an admin after the checks the
//! machine process makes at its start (the TOML parsed, every value validated, the kernel
//! built on it with the PLC program compiled). The machine takes it at its next start.

use std::path::Path;

use rtcnc_kernel::{Kernel, KernelOptions, MachineConfig};

/// Why a machine file text would not start the machine, in the words the machine would
/// use; `Ok` when it would.
pub fn validate(config_path: &Path, text: &str) -> Result<(), String> {
    let name = config_path.display().to_string();
    let mut config = MachineConfig::parse(text, &name).map_err(|e| e.to_string())?;
    // Relative paths (PLC program, tool table) resolve as they will for the machine.
    config.base_dir = config_path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    // The kernel built on copies of the persistent files: the check writes nothing of the
    // machine's.
    let scratch = std::env::temp_dir().join(format!(
        "rtcnc-machine-check-{}-{}",
        std::process::id(),
        rtcnc_kernel::link::monotonic_ns()
    ));
    std::fs::create_dir_all(&scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    for (file, name) in [
        (&mut config.files.parameters, "parameters.var"),
        (&mut config.files.plc_retain, "retain.dat"),
    ] {
        if let Some(p) = file.as_ref() {
            let src = config.base_dir.join(p);
            let dst = scratch.join(name);
            if src.exists() {
                let _ = std::fs::copy(&src, &dst);
            }
            *file = Some(dst);
        }
    }
    let built = Kernel::build(&config, KernelOptions::default()).map(drop);
    let _ = std::fs::remove_dir_all(&scratch);
    built.map_err(|e| e.to_string())
}

/// The variables of the machine's PLC program (compiled from its file here, as the
/// machine compiles it), or why there are none.
pub fn plc_variables(
    config: &MachineConfig,
) -> Result<Vec<crate::models::PlcVariableInfo>, String> {
    let plc = config.plc.as_ref().ok_or_else(|| {
        "the machine file has no [plc]: the kernel's direct logic runs".to_string()
    })?;
    let program =
        rtcnc_plc::compile_file(&config.resolve(&plc.program)).map_err(|e| e.to_string())?;
    Ok(program
        .variables()
        .into_iter()
        .map(|v| crate::models::PlcVariableInfo {
            path: v.path,
            type_name: v.type_name,
            retain: v.retain,
            location: v.location.map(|a| a.to_string()),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mill() -> (std::path::PathBuf, String) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/sim-mill.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        (path, text)
    }

    #[test]
    fn the_shipped_mill_passes_and_a_broken_value_is_refused_with_its_key() {
        let (path, text) = mill();
        assert_eq!(validate(&path, &text), Ok(()));
        let bad = text.replacen("max_velocity = 100.0", "max_velocity = -1.0", 1);
        let e = validate(&path, &bad).unwrap_err();
        assert!(e.contains("max_velocity"), "{e}");
        let e = validate(&path, "[machine\nname = 1").unwrap_err();
        assert!(e.contains("sim-mill.toml"), "{e}");
    }

    #[test]
    fn a_plc_program_that_does_not_compile_is_refused_as_at_start_up() {
        let (path, text) = mill();
        let bad = text.replace("../examples/plc/mill.st", "../examples/plc/no-such-file.st");
        let e = validate(&path, &bad).unwrap_err();
        assert!(e.contains("no-such-file.st"), "{e}");
    }

    #[test]
    fn the_mills_plc_variables_include_its_signals_with_their_types() {
        let (path, _) = mill();
        let config = MachineConfig::load(&path).unwrap();
        let vars = plc_variables(&config).unwrap();
        let door = vars
            .iter()
            .find(|v| v.path.eq_ignore_ascii_case("Mill.door_closed"))
            .expect("Mill.door_closed");
        assert_eq!(door.type_name, "BOOL");
    }
}
