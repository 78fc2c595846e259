//! The machine-logic task: either the machine's Structured Text program (rtcnc-plc) scanned
//! on the machine interface, or, when the configuration has no `[plc]`, the kernel's direct
//! logic (spindle, coolant and tool change passed straight to the machine, user M codes
//! acknowledged at once).

use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{DriveFeedback, RetainSnapshot, Runtime, Signal};
use rtcnc_rt::{Context, PiMutex, SeqlockWriter};

use crate::fault::{FaultCode, TaskName};
use crate::shared::{Feedback, LogicOutputs, LogicRequests, Shared, Snapshot};

pub(crate) enum Logic {
    Direct,
    /// Shared under a PI mutex with the operator side (PLC variables: read, force), which
    /// holds it only for a look-up.
    Plc(Arc<PiMutex<Runtime>>),
}

pub(crate) struct LogicStage {
    shared: Shared,
    logic: Logic,
    feedback: Snapshot<Feedback>,
    requests: Snapshot<LogicRequests>,
    outputs: SeqlockWriter<LogicOutputs>,
    /// What the PLC program said in its last scan.
    plc: PlcAnswers,
    fault_latched: bool,
    has_tool_changer: bool,
    /// The operator's resets seen so far.
    resets_seen: u32,
    /// A reset is held until this time, so that the PLC's task (which may run only every
    /// few periods) sees it.
    reset_until: Duration,
    /// Where the PLC task leaves its RETAIN values for the background task to save.
    retain: Option<Arc<PiMutex<RetainSnapshot>>>,
    /// The PLC's auxiliary axes: (axis index in the PLC, joint).
    plc_axes: Vec<(usize, usize)>,
}

impl LogicStage {
    pub(crate) fn new(
        shared: Shared,
        logic: Logic,
        outputs: SeqlockWriter<LogicOutputs>,
        has_tool_changer: bool,
    ) -> Self {
        LogicStage {
            feedback: Snapshot::new(shared.feedback.clone()),
            requests: Snapshot::new(shared.requests.clone()),
            resets_seen: 0,
            shared,
            logic,
            outputs,
            plc: PlcAnswers::default(),
            fault_latched: false,
            has_tool_changer,
            reset_until: Duration::ZERO,
            retain: None,
            plc_axes: Vec::new(),
        }
    }

    /// The PLC's auxiliary axes (axis index in the PLC, joint): their drives' feedback goes
    /// to the PLC before each period's scan, their set-points to position control after it.
    pub(crate) fn with_plc_axes(mut self, axes: Vec<(usize, usize)>) -> Self {
        self.plc_axes = axes;
        self
    }

    /// Hands the RETAIN values to `snapshot` after every scan (the disk is not touched here).
    pub(crate) fn with_retain(mut self, snapshot: Arc<PiMutex<RetainSnapshot>>) -> Self {
        self.retain = Some(snapshot);
        self
    }

    pub(crate) fn scan(&mut self, ctx: &mut Context<'_>) {
        // Borrowed, not copied: the feedback image is several hundred bytes.
        let fb: &Feedback = self.feedback.get();
        let req: &LogicRequests = self.requests.get();
        let now = Duration::from_nanos(ctx.release_time().as_nanos());
        let mut out = LogicOutputs::default();
        let mut fault = None;
        let reset = req.reset_count != self.resets_seen;
        self.resets_seen = req.reset_count;
        match &mut self.logic {
            Logic::Direct => direct(&mut out, req, fb, self.has_tool_changer),
            Logic::Plc(plc) => {
                let mut plc = plc.lock();
                let plc: &mut Runtime = &mut plc;
                if reset {
                    let longest = plc
                        .program()
                        .tasks()
                        .iter()
                        .filter_map(|t| t.interval)
                        .max()
                        .unwrap_or(Duration::ZERO);
                    self.reset_until = now + longest;
                }
                // The PLC's tasks run at their own intervals (mill.st: 4 ms); in the calls
                // between, a scan would only copy the images, so the answers of the last
                // scan stand and only what the kernel derives from the feedback is renewed.
                for &(axis, joint) in &self.plc_axes {
                    let bit = 1u32 << joint;
                    plc.set_axis_drive(
                        axis,
                        DriveFeedback {
                            position: fb.position.get(joint).copied().unwrap_or(0.0),
                            enabled: fb.enabled & bit != 0,
                            faulted: fb.faulted & bit != 0,
                        },
                    );
                }
                if plc.is_due(now) {
                    let estop_reset = now <= self.reset_until && self.reset_until > Duration::ZERO;
                    self.plc = plc_scan(plc, req, estop_reset, fb, now);
                    // A copy into preallocated slots; if the saver holds the snapshot just
                    // now, the next scan refreshes it.
                    if let Some(snapshot) = self.retain.as_ref().and_then(|r| r.try_lock()) {
                        let mut snapshot = snapshot;
                        plc.update_retain_snapshot(&mut snapshot);
                    }
                } else if !self.plc_axes.is_empty() {
                    // The drives take a set-point every servo period: the axes go on
                    // between the program's scans.
                    plc.advance_axes(now);
                }
                plc_axis_setpoints(plc, &self.plc_axes, now, &mut out);
                if self.plc.failed {
                    // The kernel's fault says "logic"; the PLC's own record (code, POU,
                    // line) goes beside it for the operator.
                    fault = Some(0.0);
                    if !self.fault_latched {
                        if let Some(mut slot) = self.shared.plc_fault.try_lock() {
                            *slot = plc.fault().cloned();
                        }
                    }
                } else if self.fault_latched {
                    // Running again after a reset: the record is history.
                    if let Some(mut slot) = self.shared.plc_fault.try_lock() {
                        *slot = None;
                    }
                }
                self.plc.apply(&mut out, req, fb, self.has_tool_changer);
            }
        }
        if out != self.outputs.value() {
            self.outputs.publish(out);
        }
        let faulted = fault.is_some() || out.machine_fault;
        if faulted && !self.fault_latched {
            let code = fault.unwrap_or(out.machine_fault_code as f64);
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

/// The set-points of the PLC's auxiliary axes for position control.
fn plc_axis_setpoints(
    plc: &Runtime,
    axes: &[(usize, usize)],
    now: Duration,
    out: &mut LogicOutputs,
) {
    if axes.is_empty() {
        return;
    }
    // A stopped PLC leaves its axes where they are, unpowered.
    let stopped = plc.fault().is_some();
    let sp = &mut out.plc_axes;
    sp.time_ns = now.as_nanos() as u64;
    for (i, &(axis, joint)) in axes.iter().enumerate().take(crate::config::MAX_PLC_AXES) {
        let Some(s) = plc.axis_at(axis) else { continue };
        sp.count = i as u8 + 1;
        sp.joint[i] = joint as u8;
        if s.power_requested && !stopped {
            sp.power |= 1 << i;
        }
        sp.position[i] = s.drive_position;
        if !stopped {
            sp.velocity[i] = s.velocity;
            sp.acceleration[i] = s.acceleration;
        }
    }
}

fn direct(out: &mut LogicOutputs, req: &LogicRequests, fb: &Feedback, has_tool_changer: bool) {
    out.out_spindle_enable = req.spindle_on;
    out.out_spindle_rpm = if req.spindle_reverse {
        -req.spindle_rpm
    } else {
        req.spindle_rpm
    };
    out.spindle_at_speed = req.spindle_on && fb.spindle_at_speed;
    out.out_mist = req.mist;
    out.out_flood = req.flood;
    out.out_tool_number = req.tool_number;
    out.out_tool_start = req.tool_change_request && has_tool_changer;
    out.tool_change_done = if has_tool_changer {
        req.tool_change_request && fb.tool_change_done
    } else {
        req.tool_change_request
    };
    out.m_code_done = req.m_code_request;
    out.feed_hold_request = false;
    out.machine_fault = false;
    out.estop_chain_ok = !fb.estop;
}

/// What the PLC program's signals and output image said after a scan.
#[derive(Debug, Clone, Copy, Default)]
struct PlcAnswers {
    digital: u64,
    spindle_enable: bool,
    spindle_rpm: f64,
    spindle_at_speed: bool,
    mist: bool,
    flood: bool,
    feed_hold: bool,
    tool_change_done: bool,
    /// `None`: the signal is not mapped.
    estop_chain_out: Option<bool>,
    m_code_done: bool,
    machine_fault: bool,
    machine_fault_code: i64,
    /// The scan faulted (the PLC stopped with its outputs at their safe values).
    failed: bool,
}

impl PlcAnswers {
    /// The logic's outputs: the PLC's answers combined with the kernel's requests and the
    /// feedback of this period.
    fn apply(
        &self,
        out: &mut LogicOutputs,
        req: &LogicRequests,
        fb: &Feedback,
        has_tool_changer: bool,
    ) {
        out.out_digital = self.digital;
        // Unmapped signals from the PLC keep the kernel's neutral value (not the signal's
        // safe value, which is for a faulted PLC).
        out.out_spindle_enable = self.spindle_enable;
        out.out_spindle_rpm = self.spindle_rpm;
        out.spindle_at_speed = self.spindle_at_speed;
        out.out_mist = self.mist;
        out.out_flood = self.flood;
        out.feed_hold_request = self.feed_hold;
        // With a timed changer the PLC's acknowledgement is its interlock (e.g. the spindle
        // has stopped): only then does the changer start, and the change is done when the
        // changer says so. Without one the PLC's acknowledgement is the change (it drives
        // the changer's devices itself).
        out.out_tool_start = req.tool_change_request && self.tool_change_done && has_tool_changer;
        out.out_tool_number = req.tool_number;
        out.tool_change_done = self.tool_change_done && (!has_tool_changer || fb.tool_change_done);
        out.estop_chain_ok = match self.estop_chain_out {
            Some(v) => v && !fb.estop,
            None => !fb.estop,
        };
        out.m_code_done = self.m_code_done;
        out.machine_fault = self.machine_fault;
        out.machine_fault_code = self.machine_fault_code;
        if self.failed {
            // A faulted PLC has driven its outputs to their safe values: hold the feed.
            out.feed_hold_request = true;
        }
    }
}

/// One PLC scan on the machine interface. The details of a runtime fault are in the PLC's
/// own fault record (`Runtime::fault`); the kernel's fault says "logic".
fn plc_scan(
    plc: &mut Runtime,
    req: &LogicRequests,
    estop_reset: bool,
    fb: &Feedback,
    now: Duration,
) -> PlcAnswers {
    let b = |v: bool| if v { 1.0 } else { 0.0 };
    let to_plc = [
        (Signal::EstopChainIn, b(!fb.estop)),
        (Signal::EstopReset, b(estop_reset)),
        (Signal::MachineOnRequest, b(req.machine_on_request)),
        (Signal::ProgramRunning, b(req.program_running)),
        (Signal::AxesHomed, b(req.homed)),
        (Signal::SpindleOn, b(req.spindle_on)),
        (Signal::SpindleReverse, b(req.spindle_reverse)),
        (Signal::SpindleSpeedCommand, req.spindle_rpm),
        (Signal::SpindleSpeedActual, fb.spindle_rpm),
        (Signal::CoolantMist, b(req.mist)),
        (Signal::CoolantFlood, b(req.flood)),
        (Signal::ToolChangeRequest, b(req.tool_change_request)),
        (Signal::ToolNumber, f64::from(req.tool_number)),
        (Signal::MCodeRequest, b(req.m_code_request)),
        (Signal::MCodeNumber, f64::from(req.m_code)),
        (
            Signal::MCodeP,
            if req.m_p.is_finite() { req.m_p } else { 0.0 },
        ),
        (
            Signal::MCodeQ,
            if req.m_q.is_finite() { req.m_q } else { 0.0 },
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
    let flag = |s: Signal| plc.signal(s).is_some_and(|v| v != 0.0);
    let number = |s: Signal| plc.signal(s).unwrap_or(0.0);
    PlcAnswers {
        digital,
        spindle_enable: flag(Signal::SpindleEnable),
        spindle_rpm: number(Signal::SpindleSpeedOut),
        spindle_at_speed: flag(Signal::SpindleAtSpeed),
        mist: flag(Signal::CoolantMistOn),
        flood: flag(Signal::CoolantFloodOn),
        feed_hold: flag(Signal::FeedHoldRequest),
        tool_change_done: flag(Signal::ToolChangeDone),
        estop_chain_out: plc.signal(Signal::EstopChainOut).map(|v| v != 0.0),
        m_code_done: flag(Signal::MCodeDone),
        machine_fault: flag(Signal::MachineFault),
        machine_fault_code: number(Signal::MachineFaultCode) as i64,
        failed: result.is_err(),
    }
}

/// Compiles and configures the machine's PLC program.
pub(crate) fn load_plc(
    path: &std::path::Path,
    compiled: Option<&Arc<rtcnc_plc::Program>>,
    signals: &std::collections::BTreeMap<String, String>,
    safe_values: &std::collections::BTreeMap<String, String>,
    axes: &[(String, usize, rtcnc_plc::AxisConfig)],
) -> Result<Runtime, crate::error::KernelError> {
    let program = match compiled {
        Some(program) => Arc::clone(program),
        None => Arc::new(rtcnc_plc::compile_file(path).map_err(|source| {
            crate::error::KernelError::PlcProgram {
                path: path.to_path_buf(),
                source,
            }
        })?),
    };
    let mut runtime = Runtime::new(program);
    let config = rtcnc_plc::PlcConfig {
        signals: signals.clone(),
        safe_values: safe_values.clone(),
        axes: axes
            .iter()
            .map(|(var, _, limits)| (var.clone(), *limits))
            .collect(),
    };
    runtime
        .configure(&config)
        .map_err(crate::error::KernelError::PlcSignals)?;
    Ok(runtime)
}
