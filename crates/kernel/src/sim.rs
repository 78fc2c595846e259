//! The simulation side: a kernel run in virtual time (what `rtcnc sim` and the
//! whole-machine tests use), and the simulated machine's own accessors for a kernel built
//! on one.

use std::any::Any;
use std::sync::Arc;
use std::time::Duration;

use rtcnc_ecat_slave_sim::Segment;
use rtcnc_ecat_slave_sim::dio::DioTerminal;
use rtcnc_ecat_slave_sim::drive::CspDrive;
use rtcnc_ecat_slave_sim::segment::{Fault as SegmentFault, SegmentError};
use rtcnc_ethercat::SimulatedBus;
use rtcnc_fieldbus::sim::SimulatedMachine;
use rtcnc_rt::{PiMutex, RingConsumer, RunError, SeqlockCopy, VirtualRunner};

use crate::config::MachineConfig;
use crate::kernel::{Kernel, KernelHandle};
use crate::messages::Status;
use crate::servo::{Sample, ServoStage};

/// The simulated machine under a running kernel, for what an operator or a test does to
/// the machine itself: press the e-stop, open the door, turn the handwheel, inject faults.
/// Got from [`KernelHandle::simulated_machine`] when the kernel's fieldbus is a
/// [`SimulatedMachine`].
#[derive(Clone)]
pub struct SimulatedMachineHandle {
    drives: Arc<PiMutex<ServoStage<SimulatedMachine>>>,
}

impl SimulatedMachineHandle {
    /// The handle when the drive stage's bus is the simulated machine.
    pub(crate) fn of<B: rtcnc_fieldbus::Fieldbus + 'static>(
        drives: &Arc<PiMutex<ServoStage<B>>>,
    ) -> Option<SimulatedMachineHandle> {
        (drives as &dyn Any)
            .downcast_ref::<Arc<PiMutex<ServoStage<SimulatedMachine>>>>()
            .map(|drives| SimulatedMachineHandle {
                drives: Arc::clone(drives),
            })
    }

    /// Acts on the machine, between two exchanges (under the drive stage's lock).
    pub fn with<R>(&self, f: impl FnOnce(&mut SimulatedMachine) -> R) -> R {
        f(&mut self.drives.lock().bus)
    }
}

/// The simulated EtherCAT devices under a kernel whose master runs on them
/// (`[fieldbus.simulation]`): faults to inject as on a real bus, and the loads' true
/// positions. Got from [`KernelHandle::simulated_ethercat`].
#[derive(Clone)]
pub struct SimulatedEthercatHandle {
    segment: Arc<PiMutex<Segment>>,
    /// Per joint, the bus position of its drive.
    drive_of_joint: Vec<usize>,
}

impl SimulatedEthercatHandle {
    /// The handle when the drive stage's bus is a master on simulated devices.
    pub(crate) fn of<B: rtcnc_fieldbus::Fieldbus + 'static>(
        drives: &Arc<PiMutex<ServoStage<B>>>,
        config: &MachineConfig,
    ) -> Option<SimulatedEthercatHandle> {
        let drives =
            (drives as &dyn Any).downcast_ref::<Arc<PiMutex<ServoStage<SimulatedBus>>>>()?;
        let segment = Arc::clone(drives.lock().bus.segment());
        let mut drive_of_joint = vec![0; config.joints.len()];
        for (position, slave) in config
            .fieldbus
            .ethercat
            .iter()
            .flat_map(|e| e.master.slaves.iter())
            .enumerate()
        {
            if let rtcnc_ethercat::SlaveConfig::Cia402 { joint, .. } = slave
                && let Some(slot) = drive_of_joint.get_mut(*joint)
            {
                *slot = position;
            }
        }
        Some(SimulatedEthercatHandle {
            segment,
            drive_of_joint,
        })
    }

    /// Puts a fault into the segment (frame loss, a fall to SAFE-OP, a drive fault, link
    /// down); devices are named by bus position.
    pub fn inject(&self, fault: SegmentFault) -> Result<(), SegmentError> {
        self.segment.lock().inject(fault)
    }

    /// Takes a fault out again.
    pub fn clear(&self, fault: SegmentFault) -> Result<(), SegmentError> {
        self.segment.lock().clear(fault)
    }

    /// The bus position of the drive that moves `joint`.
    pub fn drive_position(&self, joint: usize) -> Option<usize> {
        self.drive_of_joint.get(joint).copied()
    }

    /// The true position of `joint`'s load (its simulated drive's motor, before the
    /// encoder), and its velocity.
    pub fn true_state(&self, joint: usize) -> Option<(f64, f64)> {
        let position = self.drive_position(joint)?;
        let mut segment = self.segment.lock();
        let drive = segment
            .slave_mut(position)?
            .application_mut()
            .as_any_mut()
            .downcast_mut::<CspDrive>()?;
        Some(drive.true_state())
    }

    /// Sets the inputs of the I/O terminal at bus position `position`; false if there is
    /// none there.
    pub fn set_terminal_inputs(&self, position: usize, levels: u8) -> bool {
        let mut segment = self.segment.lock();
        let Some(terminal) = segment.slave_mut(position).and_then(|s| {
            s.application_mut()
                .as_any_mut()
                .downcast_mut::<DioTerminal>()
        }) else {
            return false;
        };
        terminal.set_inputs(levels);
        true
    }

    /// The output levels of the I/O terminal at bus position `position`, if one is there.
    pub fn terminal_outputs(&self, position: usize) -> Option<u8> {
        let mut segment = self.segment.lock();
        segment
            .slave_mut(position)?
            .application_mut()
            .as_any_mut()
            .downcast_mut::<DioTerminal>()
            .map(|t| t.outputs())
    }

    /// Acts on the segment directly (its devices, counters), between two exchanges.
    pub fn with<R>(&self, f: impl FnOnce(&mut Segment) -> R) -> R {
        f(&mut self.segment.lock())
    }
}

/// A kernel on the virtual-time runner.
pub struct Simulation {
    runner: VirtualRunner,
    handle: KernelHandle,
    /// The status as `run_until` last read it (one copy per period).
    status: SeqlockCopy<Status>,
    samples: Option<RingConsumer<Sample>>,
    period: Duration,
}

impl Simulation {
    /// Puts a built kernel on the virtual-time runner.
    pub fn new(kernel: Kernel) -> Simulation {
        let period = kernel.handle.config().servo_period();
        Simulation {
            runner: VirtualRunner::new(kernel.tasks),
            status: SeqlockCopy::new(kernel.handle.status_reader()),
            handle: kernel.handle,
            samples: kernel.samples,
            period,
        }
    }

    /// Measures the host processor time of every task (see
    /// `VirtualRunner::with_host_profile`); the simulated run is the same.
    pub fn with_host_profile(self) -> Simulation {
        Simulation {
            runner: self.runner.with_host_profile(),
            ..self
        }
    }

    /// The operator side.
    pub fn handle(&self) -> &KernelHandle {
        &self.handle
    }

    /// The runner (monitor, trace).
    pub fn runner(&self) -> &VirtualRunner {
        &self.runner
    }

    /// The servo period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Virtual time now.
    pub fn now(&self) -> Duration {
        Duration::from_nanos(self.runner.now().as_nanos())
    }

    /// Runs `cycles` servo periods, handing every recorded sample to `sink`.
    pub fn run_cycles(
        &mut self,
        cycles: u64,
        sink: &mut dyn FnMut(&Sample),
    ) -> Result<(), RunError> {
        for _ in 0..cycles {
            self.runner.run_for(self.period)?;
            if let Some(samples) = self.samples.as_mut() {
                samples.drain_with(&mut *sink);
            }
        }
        Ok(())
    }

    /// Runs until `done(status)` holds or `limit` has passed; returns whether it held.
    pub fn run_until(
        &mut self,
        limit: Duration,
        sink: &mut dyn FnMut(&Sample),
        mut done: impl FnMut(&Status) -> bool,
    ) -> Result<bool, RunError> {
        let end = self.now() + limit;
        while self.now() < end {
            self.run_cycles(1, sink)?;
            if done(self.status.get()) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Gives the runner back (for its recording).
    pub fn into_runner(self) -> VirtualRunner {
        self.runner
    }
}
