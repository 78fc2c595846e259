//! The machines built into the binary: the shipped machine files of `configs/` with the
//! files they name (PLC program, tool table), so that `rtcnc sim part.ngc` runs from any
//! folder and an installed `rtcnc` needs no checkout. `--machine` takes a shipped machine's
//! name or a machine file's path.
//!
//! A shipped machine is written, when it is used, into a folder of its own under the user's
//! data folder (`$XDG_DATA_HOME/rtcnc/machines/<name>`, else
//! `~/.local/share/rtcnc/machines/<name>`), as LinuxCNC copies its sample configurations
//! into `~/linuxcnc/configs`: the machine keeps persistent files there (tool table,
//! parameters, users, programs) beside its machine file. The machine file and PLC program
//! are the binary's own and are rewritten when they differ; a tool table already there is
//! the machine's state and is kept.

use std::path::{Path, PathBuf};

use anyhow::{Context as _, bail};

/// The machine `--machine` means when it is not given.
pub const DEFAULT: &str = "sim-mill";

/// A machine built into the binary.
pub struct Shipped {
    /// What `--machine` calls it (the file name in `configs/` without `.toml`).
    pub name: &'static str,
    /// The machine file's text, with the paths it names made relative to its own folder.
    machine_file: &'static str,
    /// The other files: name, text, whether it is state the machine changes (kept once
    /// written).
    files: &'static [(&'static str, &'static str, bool)],
}

/// How a machine file in `configs/` names its PLC program in the examples.
const PLC_IN_CONFIGS: &str = "program = \"../examples/plc/";

/// The shipped machines, the default first.
pub const SHIPPED: &[Shipped] = &[
    Shipped {
        name: "sim-mill",
        machine_file: include_str!("../../../configs/sim-mill.toml"),
        files: &[
            (
                "mill.st",
                include_str!("../../../examples/plc/mill.st"),
                false,
            ),
            (
                "sim-mill.tbl",
                include_str!("../../../configs/sim-mill.tbl"),
                true,
            ),
        ],
    },
    Shipped {
        name: "sim-lathe",
        machine_file: include_str!("../../../configs/sim-lathe.toml"),
        files: &[(
            "sim-lathe.tbl",
            include_str!("../../../configs/sim-lathe.tbl"),
            true,
        )],
    },
    Shipped {
        name: "sim-mill-carousel",
        machine_file: include_str!("../../../configs/sim-mill-carousel.toml"),
        files: &[
            (
                "mill_carousel.st",
                include_str!("../../../examples/plc/mill_carousel.st"),
                false,
            ),
            (
                "sim-mill-carousel.tbl",
                include_str!("../../../configs/sim-mill-carousel.tbl"),
                true,
            ),
        ],
    },
    Shipped {
        name: "sim-5axis-trt",
        machine_file: include_str!("../../../configs/sim-5axis-trt.toml"),
        files: &[(
            "sim-5axis-trt.tbl",
            include_str!("../../../configs/sim-5axis-trt.tbl"),
            true,
        )],
    },
    Shipped {
        name: "sim-5axis-head",
        machine_file: include_str!("../../../configs/sim-5axis-head.toml"),
        files: &[(
            "sim-5axis-head.tbl",
            include_str!("../../../configs/sim-5axis-head.tbl"),
            true,
        )],
    },
    Shipped {
        name: "sim-gantry-12",
        machine_file: include_str!("../../../configs/sim-gantry-12.toml"),
        files: &[],
    },
    Shipped {
        name: "experiment-1",
        machine_file: include_str!("../../../configs/experiment-1.toml"),
        files: &[],
    },
    Shipped {
        name: "ethercat-sim-12",
        machine_file: include_str!("../../../configs/ethercat-sim-12.toml"),
        files: &[],
    },
    Shipped {
        name: "bench-xyz",
        machine_file: include_str!("../../../configs/bench-xyz.toml"),
        files: &[],
    },
];

impl Shipped {
    /// The machine file as written into the machine's folder: the PLC program beside it.
    pub fn machine_text(&self) -> String {
        self.machine_file.replace(PLC_IN_CONFIGS, "program = \"")
    }

    /// The `name` the machine file gives the machine.
    pub fn title(&self) -> String {
        rtcnc_kernel::MachineConfig::parse(&self.machine_text(), self.name)
            .map(|c| c.machine.name)
            .unwrap_or_else(|e| format!("(invalid: {e})"))
    }

    /// Writes the machine's files into `dir` (created) and returns its machine file's path.
    pub fn write_into(&self, dir: &Path) -> anyhow::Result<PathBuf> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let machine = dir.join(format!("{}.toml", self.name));
        let text = self.machine_text();
        let own = [(machine.clone(), text.as_str(), false)];
        let others = self
            .files
            .iter()
            .map(|&(n, t, state)| (dir.join(n), t, state));
        for (path, text, state) in own.into_iter().chain(others) {
            let same = match std::fs::read_to_string(&path) {
                Ok(old) => state || old == text,
                Err(_) => false,
            };
            if !same {
                std::fs::write(&path, text)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
        }
        Ok(machine)
    }
}

/// The shipped machine called `name`.
pub fn shipped(name: &str) -> Option<&'static Shipped> {
    SHIPPED.iter().find(|m| m.name == name)
}

/// The folder the shipped machines are written into.
pub fn data_folder() -> anyhow::Result<PathBuf> {
    let base = match std::env::var_os("XDG_DATA_HOME").filter(|v| !v.is_empty()) {
        Some(d) => PathBuf::from(d),
        None => match std::env::var_os("HOME").filter(|v| !v.is_empty()) {
            Some(home) => Path::new(&home).join(".local/share"),
            None => bail!("neither XDG_DATA_HOME nor HOME is set: give --machine a machine file"),
        },
    };
    Ok(base.join("rtcnc").join("machines"))
}

/// The machine file `--machine` means: an existing file as it is; else the shipped machine
/// of that name, written into its folder; else the path as given (whose loading says what
/// is wrong with it).
pub fn locate(arg: &Path) -> anyhow::Result<PathBuf> {
    if arg.is_file() {
        return Ok(arg.to_path_buf());
    }
    let Some(name) = arg
        .to_str()
        .filter(|s| !s.contains('/') && !s.ends_with(".toml"))
    else {
        return Ok(arg.to_path_buf());
    };
    match shipped(name) {
        Some(m) => m.write_into(&data_folder()?.join(m.name)),
        None => {
            let names: Vec<&str> = SHIPPED.iter().map(|m| m.name).collect();
            bail!(
                "no machine file and no shipped machine named '{name}' (shipped: {})",
                names.join(", ")
            )
        }
    }
}
