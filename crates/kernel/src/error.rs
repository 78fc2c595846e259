//! Why a kernel could not be built: [`KernelError`], with the underlying error as its
//! source.

use std::path::PathBuf;

use rtcnc_fieldbus::FieldbusError;
use rtcnc_gcode::params::ParamFileError;
use rtcnc_gcode::tools::ToolTableError;

use crate::config::ConfigError;

/// Why the kernel could not be built or did not pass its power-up self-test. The message
/// says what failed; the cause is the error's [`source`](std::error::Error::source), so a
/// report that walks the chain (`anyhow`'s `{:#}`) prints it once, after the message.
#[derive(Debug, thiserror::Error)]
pub enum KernelError {
    /// The machine file.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The EtherCAT master did not bring the bus up (interface, identities, SDOs, AL
    /// states).
    #[error("EtherCAT start-up")]
    Ethercat(#[source] rtcnc_ethercat::StartError),
    /// The simulated machine refused its configuration.
    #[error("simulated machine")]
    SimulatedMachine(#[source] rtcnc_fieldbus::sim::ConfigError),
    /// A servo loop refused its configuration.
    #[error("joints[{joint}].servo")]
    Servo {
        /// The joint.
        joint: usize,
        /// Why.
        #[source]
        source: rtcnc_servo::ConfigError,
    },
    /// The kinematics does not have the machine's joints.
    #[error(
        "kinematics: it has {found} joints, the machine file has {expected} joints driven by axes"
    )]
    Kinematics {
        /// Joints the machine file's axes drive.
        expected: usize,
        /// Joints of the kinematics.
        found: usize,
    },
    /// The planner refused the machine.
    #[error("motion planner")]
    Motion(#[from] rtcnc_motion::MotionError),
    /// An on-line trajectory generator (jog, homing, independent joints) refused its limits.
    #[error("on-line trajectory generator")]
    Generator(#[from] rtcnc_motion::otg::OtgError),
    /// The PLC program did not load.
    #[error("plc program {}", path.display())]
    PlcProgram {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: rtcnc_plc::LoadError,
    },
    /// The PLC program's signal map (`plc.signals`, `plc.safe_values`) was refused.
    #[error("plc signals")]
    PlcSignals(#[source] rtcnc_plc::ConfigError),
    /// The PLC's RETAIN file could not be read.
    #[error("plc retain file {}", path.display())]
    PlcRetain {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The executive refused the task set.
    #[error("executive")]
    Executive(#[from] rtcnc_rt::ConfigError),
    /// The power-up self-test failed.
    #[error("self-test: {check}")]
    SelfTest {
        /// Which check.
        check: &'static str,
        /// What it found.
        #[source]
        source: SelfTestFailure,
    },
    /// The simulated machine's accessors were asked of a kernel on another fieldbus.
    #[error(
        "the kernel's fieldbus is not the simulated machine, or the simulated EtherCAT devices, asked for (fieldbus.kind = \"sim\", or \"ethercat\" with [fieldbus.simulation])"
    )]
    NotSimulated,
}

impl KernelError {
    /// Stable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            KernelError::Config(e) => e.code(),
            KernelError::SimulatedMachine(_) => "kernel.fieldbus",
            KernelError::Ethercat(e) => e.code(),
            KernelError::Servo { .. } => "kernel.servo",
            KernelError::Kinematics { .. } => "kernel.kinematics",
            KernelError::Motion(_) | KernelError::Generator(_) => "kernel.motion",
            KernelError::PlcProgram { .. }
            | KernelError::PlcSignals(_)
            | KernelError::PlcRetain { .. } => "kernel.plc",
            KernelError::Executive(_) => "kernel.executive",
            KernelError::SelfTest { .. } => "kernel.self_test",
            KernelError::NotSimulated => "kernel.not_simulated",
        }
    }

    pub(crate) fn self_test(
        check: &'static str,
        source: impl Into<SelfTestFailure>,
    ) -> KernelError {
        KernelError::SelfTest {
            check,
            source: source.into(),
        }
    }
}

/// What a failed self-test check found.
#[derive(Debug, thiserror::Error)]
pub enum SelfTestFailure {
    /// The parameter file.
    #[error(transparent)]
    ParameterFile(#[from] ParamFileError),
    /// The tool table.
    #[error(transparent)]
    ToolTable(#[from] ToolTableError),
    /// A folder of the persistent files is not there.
    #[error("{}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A folder of the persistent files cannot be written.
    #[error("{} is read-only", path.display())]
    ReadOnly {
        /// The folder.
        path: PathBuf,
    },
    /// Not every configured drive answers.
    #[error("{answering} drives answer, {configured} are configured")]
    DriveCount {
        /// Drives on the bus.
        answering: usize,
        /// Joints in the machine file.
        configured: usize,
    },
    /// The exchange with the drives failed.
    #[error(transparent)]
    Exchange(#[from] FieldbusError),
    /// A drive is faulted.
    #[error("drive {joint} reports a fault")]
    DriveFault {
        /// The joint's name.
        joint: String,
    },
    /// The bus's digital I/O is not the machine file's.
    #[error("the process image does not match the configuration")]
    ImageMismatch,
}
