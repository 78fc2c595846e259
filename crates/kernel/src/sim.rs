//! The simulation side: a kernel run in virtual time (what `rtcnc sim` and the
//! whole-machine tests use), and the simulated machine's own accessors for a kernel built
//! on one.

use std::any::Any;
use std::sync::Arc;
use std::time::Duration;

use rtcnc_fieldbus::sim::SimulatedMachine;
use rtcnc_rt::{PiMutex, RingConsumer, RunError, VirtualRunner};

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

/// A kernel on the virtual-time runner.
pub struct Simulation {
    runner: VirtualRunner,
    handle: KernelHandle,
    samples: Option<RingConsumer<Sample>>,
    period: Duration,
}

impl Simulation {
    /// Puts a built kernel on the virtual-time runner.
    pub fn new(kernel: Kernel) -> Simulation {
        let period = kernel.handle.config().servo_period();
        Simulation {
            runner: VirtualRunner::new(kernel.tasks),
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
            if done(&self.handle.status()) {
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
