//! The machine-logic task: either the machine's Structured Text program (rtcnc-plc) scanned
//! on the machine interface, or, when the configuration has no `[plc]`, the kernel's direct
//! logic (spindle, coolant and tool change passed straight to the machine, user M codes
//! acknowledged at once).

use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{RetainSnapshot, Runtime, Signal};
use rtcnc_rt::{Context, PiMutex};

use crate::fault::{FaultCode, TaskName};
use crate::shared::{Feedback, MachineInterface, Shared};

pub(crate) enum Logic {
    Direct,
    Plc(Box<Runtime>),
}

pub(crate) struct LogicStage {
    shared: Shared,
    logic: Logic,
    fault_latched: bool,
    has_tool_changer: bool,
    /// A reset is held until this time, so that the PLC's task (which may run only every
    /// few periods) sees it.
    reset_until: Duration,
    /// Where the PLC task leaves its RETAIN values for the background task to save.
    retain: Option<Arc<PiMutex<RetainSnapshot>>>,
}

impl LogicStage {
    pub(crate) fn new(shared: Shared, logic: Logic, has_tool_changer: bool) -> Self {
        LogicStage {
            shared,
            logic,
            fault_latched: false,
            has_tool_changer,
            reset_until: Duration::ZERO,
            retain: None,
        }
    }

    /// Hands the RETAIN values to `snapshot` after every scan (the disk is not touched here).
    pub(crate) fn with_retain(mut self, snapshot: Arc<PiMutex<RetainSnapshot>>) -> Self {
        self.retain = Some(snapshot);
        self
    }

    pub(crate) fn scan(&mut self, ctx: &mut Context<'_>) {
        let fb: Feedback = *self.shared.feedback.lock();
        let mut mi = *self.shared.machine_interface.lock();
        let now = Duration::from_nanos(ctx.release_time().as_nanos());
        let mut fault = None;
        match &mut self.logic {
            Logic::Direct => direct(&mut mi, &fb, self.has_tool_changer),
            Logic::Plc(plc) => {
                if mi.estop_reset {
                    let longest = plc
                        .program()
                        .tasks()
                        .iter()
                        .filter_map(|t| t.interval)
                        .max()
                        .unwrap_or(Duration::ZERO);
                    self.reset_until = now + longest;
                }
                mi.estop_reset = now <= self.reset_until && self.reset_until > Duration::ZERO;
                if let Err(f) = plc_scan(plc, &mut mi, &fb, now, self.has_tool_changer) {
                    fault = Some(f);
                }
                // A copy into preallocated slots; if the saver holds the snapshot just now,
                // the next scan refreshes it.
                if let Some(snapshot) = self.retain.as_ref().and_then(|r| r.try_lock()) {
                    let mut snapshot = snapshot;
                    plc.update_retain_snapshot(&mut snapshot);
                }
            }
        }
        mi.estop_reset = false;
        {
            let mut shared = self.shared.machine_interface.lock();
            // Copy back what the logic owns; the kernel's requests may have changed since.
            shared.spindle_at_speed = mi.spindle_at_speed;
            shared.tool_change_done = mi.tool_change_done;
            shared.m_code_done = mi.m_code_done;
            shared.feed_hold_request = mi.feed_hold_request;
            shared.machine_fault = mi.machine_fault;
            shared.estop_chain_ok = mi.estop_chain_ok;
            shared.machine_fault_code = mi.machine_fault_code;
            shared.out_spindle_enable = mi.out_spindle_enable;
            shared.out_spindle_rpm = mi.out_spindle_rpm;
            shared.out_mist = mi.out_mist;
            shared.out_flood = mi.out_flood;
            shared.out_tool_start = mi.out_tool_start;
            shared.out_tool_number = mi.out_tool_number;
            shared.out_digital = mi.out_digital;
            shared.estop_reset = false;
        }
        let faulted = fault.is_some() || mi.machine_fault;
        if faulted && !self.fault_latched {
            let code = fault.unwrap_or(mi.machine_fault_code as f64);
            self.shared.raise(
                ctx,
                FaultCode::LogicFault,
                TaskName::MachineLogic,
                None,
                0,
                code,
            );
        }
        self.fault_latched = faulted;
    }
}

fn direct(mi: &mut MachineInterface, fb: &Feedback, has_tool_changer: bool) {
    mi.out_spindle_enable = mi.spindle_on;
    mi.out_spindle_rpm = if mi.spindle_reverse {
        -mi.spindle_rpm
    } else {
        mi.spindle_rpm
    };
    mi.spindle_at_speed = mi.spindle_on && fb.spindle_at_speed;
    mi.out_mist = mi.mist;
    mi.out_flood = mi.flood;
    mi.out_tool_number = mi.tool_number;
    mi.out_tool_start = mi.tool_change_request && has_tool_changer;
    mi.tool_change_done = if has_tool_changer {
        mi.tool_change_request && fb.tool_change_done
    } else {
        mi.tool_change_request
    };
    mi.m_code_done = mi.m_code_request;
    mi.feed_hold_request = false;
    mi.machine_fault = false;
    mi.estop_chain_ok = !fb.estop;
}

/// One PLC scan on the machine interface; a runtime fault comes back as its code number.
fn plc_scan(
    plc: &mut Runtime,
    mi: &mut MachineInterface,
    fb: &Feedback,
    now: Duration,
    has_tool_changer: bool,
) -> Result<(), f64> {
    let b = |v: bool| if v { 1.0 } else { 0.0 };
    let to_plc = [
        (Signal::EstopChainIn, b(!fb.estop)),
        (Signal::EstopReset, b(mi.estop_reset)),
        (Signal::MachineOnRequest, b(mi.machine_on_request)),
        (Signal::ProgramRunning, b(mi.program_running)),
        (Signal::AxesHomed, b(mi.homed)),
        (Signal::SpindleOn, b(mi.spindle_on)),
        (Signal::SpindleReverse, b(mi.spindle_reverse)),
        (Signal::SpindleSpeedCommand, mi.spindle_rpm),
        (Signal::SpindleSpeedActual, fb.spindle_rpm),
        (Signal::CoolantMist, b(mi.mist)),
        (Signal::CoolantFlood, b(mi.flood)),
        (Signal::ToolChangeRequest, b(mi.tool_change_request)),
        (Signal::ToolNumber, f64::from(mi.tool_number)),
        (Signal::MCodeRequest, b(mi.m_code_request)),
        (Signal::MCodeNumber, f64::from(mi.m_code)),
        (
            Signal::MCodeP,
            if mi.m_p.is_finite() { mi.m_p } else { 0.0 },
        ),
        (
            Signal::MCodeQ,
            if mi.m_q.is_finite() { mi.m_q } else { 0.0 },
        ),
        (Signal::LimitMin, f64::from(fb.negative_limit)),
        (Signal::LimitMax, f64::from(fb.positive_limit)),
    ];
    for (signal, value) in to_plc {
        plc.set_signal(signal, value);
    }
    let inputs = plc.input_image_mut();
    for (byte, slot) in inputs.iter_mut().enumerate().take(8) {
        *slot = (fb.digital_inputs >> (8 * byte)) as u8;
    }
    let result = plc.scan(now);
    let mut digital = 0u64;
    for (byte, &v) in plc.output_image().iter().enumerate().take(8) {
        digital |= u64::from(v) << (8 * byte);
    }
    mi.out_digital = digital;
    // Unmapped signals from the PLC keep the kernel's neutral value (not the signal's
    // safe value, which is for a faulted PLC).
    let flag = |s: Signal| plc.signal(s).is_some_and(|v| v != 0.0);
    let number = |s: Signal| plc.signal(s).unwrap_or(0.0);
    mi.out_spindle_enable = flag(Signal::SpindleEnable);
    mi.out_spindle_rpm = number(Signal::SpindleSpeedOut);
    mi.spindle_at_speed = flag(Signal::SpindleAtSpeed);
    mi.out_mist = flag(Signal::CoolantMistOn);
    mi.out_flood = flag(Signal::CoolantFloodOn);
    mi.feed_hold_request = flag(Signal::FeedHoldRequest);
    // With a timed changer the PLC's acknowledgement is its interlock (e.g. the spindle
    // has stopped): only then does the changer start, and the change is done when the
    // changer says so. Without one the PLC's acknowledgement is the change (it drives the
    // changer's devices itself).
    let plc_done = flag(Signal::ToolChangeDone);
    mi.out_tool_start = mi.tool_change_request && plc_done && has_tool_changer;
    mi.out_tool_number = mi.tool_number;
    mi.tool_change_done = plc_done && (!has_tool_changer || fb.tool_change_done);
    mi.estop_chain_ok = match plc.signal(Signal::EstopChainOut) {
        Some(v) => v != 0.0 && !fb.estop,
        None => !fb.estop,
    };
    mi.m_code_done = flag(Signal::MCodeDone);
    mi.machine_fault = flag(Signal::MachineFault);
    mi.machine_fault_code = number(Signal::MachineFaultCode) as i64;
    if result.is_err() {
        // A faulted PLC has driven its outputs to their safe values: hold the feed.
        mi.feed_hold_request = true;
    }
    // The fault's details are in the PLC's own fault record; the kernel's fault says "logic".
    result.map_err(|_| -1.0)
}

/// Compiles and configures the machine's PLC program.
pub(crate) fn load_plc(
    path: &std::path::Path,
    signals: &std::collections::BTreeMap<String, String>,
    safe_values: &std::collections::BTreeMap<String, String>,
) -> Result<Runtime, String> {
    let program = rtcnc_plc::compile_file(path).map_err(|e| e.to_string())?;
    let mut runtime = Runtime::new(Arc::new(program));
    let config = rtcnc_plc::PlcConfig {
        signals: signals.clone(),
        safe_values: safe_values.clone(),
    };
    runtime
        .configure(&config)
        .map_err(|e| format!("plc signals: {e}"))?;
    Ok(runtime)
}
