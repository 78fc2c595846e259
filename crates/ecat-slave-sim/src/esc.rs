//! One EtherCAT slave controller (ESC) and the device behind it: the register space and
//! process RAM, datagram handling with the working-counter rules, the SII EEPROM interface,
//! AL control and status with AL status codes, sync managers (mailbox and buffered),
//! FMMUs, the distributed clock (receive-time latch, system time, offset, delay, drift
//! control, SYNC0) and the mailbox (CoE).
//!
//! Register numbers and bit meanings are those of ETG.1000.4 / ETG.1000.6 and the ET1100
//! data sheet's register description.

use crate::application::{Application, TransitionContext};
use crate::coe::CoeServer;
use crate::frame::{Command, read_u16, read_u32, read_u64, write_u16, write_u32, write_u64};
use crate::sii::{SiiContents, SiiImage, SyncManagerUse};

/// Registers 0x0000-0x0FFF, then process RAM 0x1000-0x1FFF.
pub const MEMORY_SIZE: usize = 0x2000;
/// Start of the process RAM.
pub const RAM_START: usize = 0x1000;

/// Register addresses (ET1100 register description).
pub mod reg {
    /// ESC type.
    pub const TYPE: usize = 0x0000;
    /// FMMUs supported.
    pub const FMMU_COUNT: usize = 0x0004;
    /// Sync managers supported.
    pub const SM_COUNT: usize = 0x0005;
    /// RAM size in KiB.
    pub const RAM_SIZE: usize = 0x0006;
    /// Port descriptor.
    pub const PORT_DESCRIPTOR: usize = 0x0007;
    /// ESC features supported.
    pub const FEATURES: usize = 0x0008;
    /// Configured station address.
    pub const STATION_ADDRESS: usize = 0x0010;
    /// Configured station alias.
    pub const STATION_ALIAS: usize = 0x0012;
    /// DL status.
    pub const DL_STATUS: usize = 0x0110;
    /// AL control.
    pub const AL_CONTROL: usize = 0x0120;
    /// AL status.
    pub const AL_STATUS: usize = 0x0130;
    /// AL status code.
    pub const AL_STATUS_CODE: usize = 0x0134;
    /// Watchdog divider.
    pub const WATCHDOG_DIVIDER: usize = 0x0400;
    /// Sync manager watchdog time.
    pub const SM_WATCHDOG: usize = 0x0420;
    /// SII configuration (owner).
    pub const SII_CONFIG: usize = 0x0500;
    /// SII control/status.
    pub const SII_CONTROL: usize = 0x0502;
    /// SII address.
    pub const SII_ADDRESS: usize = 0x0504;
    /// SII data.
    pub const SII_DATA: usize = 0x0508;
    /// FMMU 0 (16 bytes each).
    pub const FMMU: usize = 0x0600;
    /// Sync manager 0 (8 bytes each).
    pub const SM: usize = 0x0800;
    /// Receive time port 0 (4 bytes each for ports 0-3).
    pub const DC_RECEIVE_TIME_PORT0: usize = 0x0900;
    /// System time.
    pub const DC_SYSTEM_TIME: usize = 0x0910;
    /// Receive time of the processing unit.
    pub const DC_RECEIVE_TIME_PU: usize = 0x0918;
    /// System time offset.
    pub const DC_SYSTEM_TIME_OFFSET: usize = 0x0920;
    /// System time delay.
    pub const DC_SYSTEM_TIME_DELAY: usize = 0x0928;
    /// System time difference.
    pub const DC_SYSTEM_TIME_DIFFERENCE: usize = 0x092C;
    /// Cyclic unit control.
    pub const DC_CYCLIC_UNIT_CONTROL: usize = 0x0980;
    /// Activation (SYNC0/SYNC1).
    pub const DC_ACTIVATION: usize = 0x0981;
    /// SYNC0 status.
    pub const DC_SYNC0_STATUS: usize = 0x098E;
    /// Start time of cyclic operation.
    pub const DC_START_TIME: usize = 0x0990;
    /// SYNC0 cycle time.
    pub const DC_SYNC0_CYCLE: usize = 0x09A0;
}

/// The EtherCAT state machine's states (AL status bits 0-3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum AlState {
    /// INIT.
    Init = 1,
    /// PRE-OPERATIONAL: mailbox.
    PreOp = 2,
    /// BOOTSTRAP (not offered).
    Bootstrap = 3,
    /// SAFE-OPERATIONAL: inputs.
    SafeOp = 4,
    /// OPERATIONAL: inputs and outputs.
    Op = 8,
}

impl AlState {
    /// The state a register value encodes.
    pub fn from_bits(bits: u8) -> Option<Self> {
        match bits & 0x0F {
            1 => Some(Self::Init),
            2 => Some(Self::PreOp),
            3 => Some(Self::Bootstrap),
            4 => Some(Self::SafeOp),
            8 => Some(Self::Op),
            _ => None,
        }
    }

    /// The name the EtherCAT specification uses.
    pub const fn name(self) -> &'static str {
        match self {
            Self::Init => "INIT",
            Self::PreOp => "PRE-OP",
            Self::Bootstrap => "BOOT",
            Self::SafeOp => "SAFE-OP",
            Self::Op => "OP",
        }
    }
}

/// AL status codes the slave raises (ETG.1000.6 Table 11).
pub mod al_code {
    /// Invalid requested state change.
    pub const INVALID_STATE_CHANGE: u16 = 0x0011;
    /// Unknown requested state.
    pub const UNKNOWN_STATE: u16 = 0x0012;
    /// Bootstrap not supported.
    pub const BOOTSTRAP_NOT_SUPPORTED: u16 = 0x0013;
    /// Invalid mailbox configuration (PRE-OP).
    pub const INVALID_MAILBOX_CONFIGURATION: u16 = 0x0016;
    /// Synchronization error.
    pub const SYNCHRONIZATION_ERROR: u16 = 0x001A;
    /// Sync manager watchdog.
    pub const SM_WATCHDOG: u16 = 0x001B;
    /// Invalid output configuration.
    pub const INVALID_OUTPUT_CONFIGURATION: u16 = 0x001D;
    /// Invalid input configuration.
    pub const INVALID_INPUT_CONFIGURATION: u16 = 0x001E;
    /// Invalid SYNC0 cycle time.
    pub const INVALID_SYNC0_CYCLE: u16 = 0x0036;
}

/// Delay of a frame from one device's port 0 to the next one's (processing plus cable),
/// and back through the forwarding path: symmetric, as the DC delay measurement assumes.
pub const HOP_DELAY_NS: u64 = 500;

/// The largest correction of the local clock per system-time write (ns): the DC control
/// loop speeds the clock up or slows it down, it does not jump.
const DRIFT_STEP_LIMIT_NS: i64 = 1000;

/// At most this many SYNC0 events are caught up on one frame; a longer gap skips ahead.
const MAX_SYNC_EVENTS_PER_FRAME: u32 = 64;

/// The device's free-running local clock, against the segment's time base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalClock {
    /// Rate error in parts per billion (a crystal's tolerance: tens of ppm).
    pub drift_ppb: i64,
    /// Local time at time base 0 (ns).
    pub start_ns: u64,
}

impl LocalClock {
    /// The local time (ns) at time base `t`.
    pub fn local(&self, t: u64) -> u64 {
        let t = i128::from(t);
        let local = t + t * i128::from(self.drift_ppb) / 1_000_000_000 + i128::from(self.start_ns);
        local.clamp(0, i128::from(u64::MAX)) as u64
    }
}

/// How the frame's datagram addressed this device (decided by the segment walk).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Addressing {
    /// The device is the one addressed (auto-increment address 0 or configured address).
    Addressed,
    /// Not addressed (and for ARMW/FRMW: a writer).
    Other,
}

/// One simulated EtherCAT device: the controller and its application.
pub struct Slave {
    memory: Vec<u8>,
    sii: SiiImage,
    sii_contents: SiiContents,
    application: Box<dyn Application>,
    coe: CoeServer,
    state: AlState,
    error: bool,
    status_code: u16,
    mailbox_in_full: bool,
    pending_response: Option<Vec<u8>>,
    clock: LocalClock,
    drift_adjust_ns: i64,
    next_sync0: Option<u64>,
    last_free_run: Option<u64>,
    last_outputs_write: Option<u64>,
    has_downstream: bool,
    return_latch_pending: bool,
    scratch_inputs: Vec<u8>,
    scratch_outputs: Vec<u8>,
    scratch_mailbox: Vec<u8>,
    /// Frames this device has seen since power-up.
    pub frames_seen: u64,
    /// SYNC0 events run.
    pub sync_events: u64,
}

impl std::fmt::Debug for Slave {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slave")
            .field("name", &self.sii_contents.name)
            .field("state", &self.state)
            .field("error", &self.error)
            .field("status_code", &self.status_code)
            .finish_non_exhaustive()
    }
}

impl Slave {
    /// A device in INIT, powered up with its EEPROM loaded.
    pub fn new(application: Box<dyn Application>, clock: LocalClock) -> Option<Self> {
        let sii_contents = application.sii();
        let sii = SiiImage::build(&sii_contents)?;
        let mut slave = Self {
            memory: vec![0; MEMORY_SIZE],
            sii,
            sii_contents,
            application,
            coe: CoeServer::new(),
            state: AlState::Init,
            error: false,
            status_code: 0,
            mailbox_in_full: false,
            pending_response: None,
            clock,
            drift_adjust_ns: 0,
            next_sync0: None,
            last_free_run: None,
            last_outputs_write: None,
            has_downstream: false,
            return_latch_pending: false,
            scratch_inputs: Vec::new(),
            scratch_outputs: Vec::new(),
            scratch_mailbox: Vec::new(),
            frames_seen: 0,
            sync_events: 0,
        };
        slave.power_on();
        Some(slave)
    }

    fn power_on(&mut self) {
        let m = &mut self.memory;
        m[reg::TYPE] = 0x11; // an ET1100-like controller
        m[reg::FMMU_COUNT] = 8;
        m[reg::SM_COUNT] = 8;
        m[reg::RAM_SIZE] = ((MEMORY_SIZE - RAM_START) / 1024) as u8;
        m[reg::PORT_DESCRIPTOR] = 0x0F; // ports 0 and 1: MII
        // Features: DC supported (bit 2), 64-bit DC (bit 3), enhanced DC SYNC (bit 8).
        write_u16(m, reg::FEATURES, 0x010C);
        write_u16(m, reg::STATION_ALIAS, self.sii.alias());
        write_u16(m, reg::WATCHDOG_DIVIDER, 2498); // 100 µs
        write_u16(m, reg::SM_WATCHDOG, 1000); // 100 ms
        self.refresh_registers(0);
    }

    /// The device's name (from its EEPROM).
    pub fn name(&self) -> &str {
        &self.sii_contents.name
    }

    /// What its EEPROM says.
    pub fn sii_contents(&self) -> &SiiContents {
        &self.sii_contents
    }

    /// The EEPROM image.
    pub fn sii(&self) -> &SiiImage {
        &self.sii
    }

    /// The current AL state, whether the error flag is set, and the AL status code.
    pub fn al_status(&self) -> (AlState, bool, u16) {
        (self.state, self.error, self.status_code)
    }

    /// The application behind the controller.
    pub fn application_mut(&mut self) -> &mut dyn Application {
        self.application.as_mut()
    }

    /// Raw register or RAM bytes (for tests and the independent checks).
    pub fn memory(&self) -> &[u8] {
        &self.memory
    }

    /// The system time (ns) this device would report at time base `t`.
    pub fn system_time(&self, t: u64) -> u64 {
        let offset = read_u64(&self.memory, reg::DC_SYSTEM_TIME_OFFSET).unwrap_or(0);
        let local = i128::from(self.clock.local(t));
        (local + i128::from(offset) + i128::from(self.drift_adjust_ns)).rem_euclid(1 << 64) as u64
    }

    pub(crate) fn set_has_downstream(&mut self, has: bool) {
        self.has_downstream = has;
    }

    /// The device drops to `state` (a lower one) on its own with `code`, as a device does
    /// that detects a problem (e.g. a synchronisation error drops OP to SAFE-OP).
    pub fn fall_to(&mut self, state: AlState, code: u16) {
        if state < self.state {
            self.state = state;
        }
        self.error = true;
        self.status_code = code;
        self.refresh_al_status();
    }

    /// Runs what happens between frames, up to `t` (the frame's arrival at this device):
    /// SYNC0 events and the sync manager watchdog.
    pub fn advance_to(&mut self, t: u64) {
        self.frames_seen += 1;
        self.run_until(t);
    }

    /// Runs the device's own time up to `t` without a frame (one that was lost on the
    /// way): SYNC0 events and the sync manager watchdog go on by themselves.
    pub fn run_until(&mut self, t: u64) {
        let system = self.system_time(t);
        if self.state == AlState::Op
            && let Some(last) = self.last_outputs_write
            && self.sm_watchdog_enabled()
            && system.saturating_sub(last) > self.sm_watchdog_ns()
        {
            self.fall_to(AlState::SafeOp, al_code::SM_WATCHDOG);
        }
        let Some(mut next) = self.next_sync0 else {
            return;
        };
        let cycle = u64::from(read_u32(&self.memory, reg::DC_SYNC0_CYCLE).unwrap_or(0));
        if cycle == 0 {
            return;
        }
        let mut events = 0;
        while next <= system {
            if events == MAX_SYNC_EVENTS_PER_FRAME {
                // A gap of many cycles (a stalled master): skip to the present.
                let missed = (system - next) / cycle + 1;
                next = next.saturating_add(missed.saturating_mul(cycle));
                break;
            }
            self.run_cycle(cycle as f64 * 1e-9, next);
            next = next.saturating_add(cycle);
            events += 1;
        }
        self.next_sync0 = Some(next);
        write_u64(&mut self.memory, reg::DC_START_TIME, next);
    }

    fn sm_watchdog_enabled(&self) -> bool {
        self.pd_sm(SyncManagerUse::Outputs)
            .and_then(|n| self.sm(n))
            .is_some_and(|sm| sm.enabled && sm.control & 0x40 != 0)
            && self.sm_watchdog_ns() > 0
    }

    fn sm_watchdog_ns(&self) -> u64 {
        let divider = u64::from(read_u16(&self.memory, reg::WATCHDOG_DIVIDER).unwrap_or(0));
        let time = u64::from(read_u16(&self.memory, reg::SM_WATCHDOG).unwrap_or(0));
        (divider + 2) * 40 * time
    }

    /// One application cycle over the process data sync managers, starting at system time
    /// `system_ns` (the SYNC0 event's, or the outputs write's in free run).
    fn run_cycle(&mut self, period_s: f64, system_ns: u64) {
        if self.state < AlState::SafeOp {
            return;
        }
        self.application.begin_cycle(system_ns);
        self.sync_events += 1;
        let (out_len, in_len) = self.application.process_data_len();
        let outputs_valid = self.state == AlState::Op;
        let mut outputs = std::mem::take(&mut self.scratch_outputs);
        let mut inputs = std::mem::take(&mut self.scratch_inputs);
        outputs.clear();
        inputs.clear();
        inputs.resize(in_len, 0);
        if let Some(sm) = self.pd_sm(SyncManagerUse::Outputs).and_then(|n| self.sm(n)) {
            let start = usize::from(sm.start);
            if let Some(bytes) = self.memory.get(start..start + out_len) {
                outputs.extend_from_slice(bytes);
            }
        }
        let outputs_ref = (outputs_valid && outputs.len() == out_len).then_some(&outputs[..]);
        self.application.cycle(period_s, outputs_ref, &mut inputs);
        if let Some(sm) = self.pd_sm(SyncManagerUse::Inputs).and_then(|n| self.sm(n)) {
            let start = usize::from(sm.start);
            if let Some(area) = self.memory.get_mut(start..start + in_len) {
                area.copy_from_slice(&inputs);
            }
        }
        self.scratch_outputs = outputs;
        self.scratch_inputs = inputs;
    }

    /// A free-running device (no SYNC0) runs a cycle when new outputs arrive, over the
    /// time since its last cycle.
    fn free_run_cycle(&mut self, t: u64) {
        if self.dc_sync_active() {
            return;
        }
        let system = self.system_time(t);
        let period = match self.last_free_run {
            Some(last) => (system.saturating_sub(last) as f64 * 1e-9).clamp(1e-6, 0.1),
            None => 1e-3,
        };
        self.last_free_run = Some(system);
        self.run_cycle(period, system);
    }

    fn dc_sync_active(&self) -> bool {
        self.memory[reg::DC_ACTIVATION] & 0x03 == 0x03
            && read_u32(&self.memory, reg::DC_SYNC0_CYCLE).unwrap_or(0) > 0
    }

    fn refresh_al_status(&mut self) {
        let status = self.state as u16 | if self.error { 0x10 } else { 0 };
        write_u16(&mut self.memory, reg::AL_STATUS, status);
        write_u16(&mut self.memory, reg::AL_STATUS_CODE, self.status_code);
    }

    /// Writes the registers whose value is computed into the register file.
    fn refresh_registers(&mut self, t: u64) {
        self.refresh_al_status();
        // DL status: PDI operational, link and communication on port 0, on port 1 when a
        // device follows; loops closed where nothing is connected.
        let mut dl = 0x0001 | 0x0010 | 0x0200 | 0x1000 | 0x4000;
        if self.has_downstream {
            dl |= 0x0020 | 0x0800;
        } else {
            dl |= 0x0400;
        }
        write_u16(&mut self.memory, reg::DL_STATUS, dl);
        let system = self.system_time(t);
        write_u64(&mut self.memory, reg::DC_SYSTEM_TIME, system);
        // SII control: 8-byte reads supported (bit 6), never busy.
        let control = read_u16(&self.memory, reg::SII_CONTROL).unwrap_or(0);
        write_u16(
            &mut self.memory,
            reg::SII_CONTROL,
            (control & !0x8700) | 0x0040,
        );
        for n in 0..8 {
            let status = self.sm_status(n);
            if let Some(byte) = self.memory.get_mut(reg::SM + 8 * n + 5) {
                *byte = status;
            }
        }
    }

    fn sm_status(&self, n: usize) -> u8 {
        let Some(sm) = self.sm(n) else {
            return 0;
        };
        if sm.is_mailbox() {
            // Bit 3: mailbox full. The write mailbox is emptied at once by the device.
            if sm.master_reads() && self.mailbox_in_full {
                return 0x08;
            }
            return 0;
        }
        0
    }

    /// The sync manager the EEPROM gives to process data of this use.
    fn pd_sm(&self, usage: SyncManagerUse) -> Option<usize> {
        self.sii_contents
            .sync_managers
            .iter()
            .position(|sm| sm.usage == usage)
    }

    fn sm(&self, n: usize) -> Option<SyncManagerRegs> {
        let base = reg::SM + 8 * n;
        let bytes = self.memory.get(base..base + 8)?;
        Some(SyncManagerRegs {
            start: u16::from_le_bytes([bytes[0], bytes[1]]),
            length: u16::from_le_bytes([bytes[2], bytes[3]]),
            control: bytes[4],
            enabled: bytes[6] & 0x01 != 0,
        })
    }

    /// The sync manager whose area holds physical address `address`, if enabled and (for
    /// process data) active in this AL state.
    fn sm_at(&self, address: usize) -> Option<(usize, SyncManagerRegs)> {
        (0..8).find_map(|n| {
            let sm = self.sm(n)?;
            let start = usize::from(sm.start);
            let active =
                sm.enabled && sm.length > 0 && (sm.is_mailbox() || self.state >= AlState::SafeOp);
            (active && address >= start && address < start + usize::from(sm.length))
                .then_some((n, sm))
        })
    }

    /// A physical read of `data.len()` bytes at `address` into `data` (OR-ed in for
    /// broadcasts); returns whether it counts for the working counter.
    pub fn read(&mut self, address: u16, data: &mut [u8], or: bool, t: u64) -> bool {
        let start = usize::from(address);
        let end = start + data.len();
        if start >= MEMORY_SIZE {
            return false;
        }
        if start < RAM_START {
            self.refresh_registers(t);
        }
        let mut counted = true;
        // A read of the device-to-master mailbox: refused while empty, and reading its last
        // byte empties it.
        let mut mailbox_read_done = false;
        for n in 0..8 {
            let Some(sm) = self.sm(n) else { continue };
            if !(sm.enabled && sm.is_mailbox() && sm.master_reads()) {
                continue;
            }
            let sm_start = usize::from(sm.start);
            let sm_end = sm_start + usize::from(sm.length);
            if start < sm_end && end > sm_start {
                if !self.mailbox_in_full {
                    counted = false;
                } else if end >= sm_end {
                    mailbox_read_done = true;
                }
            }
        }
        if !counted {
            return false;
        }
        let available = end.min(MEMORY_SIZE) - start;
        for (d, m) in data[..available]
            .iter_mut()
            .zip(&self.memory[start..start + available])
        {
            *d = if or { *d | *m } else { *m };
        }
        if mailbox_read_done {
            self.mailbox_in_full = false;
            if let Some(next) = self.pending_response.take() {
                self.put_response(&next);
            }
        }
        true
    }

    /// A physical write of `data` at `address`; returns whether it counts.
    pub fn write(&mut self, address: u16, data: &[u8], t: u64) -> bool {
        let start = usize::from(address);
        if start >= MEMORY_SIZE {
            return false;
        }
        let end = (start + data.len()).min(MEMORY_SIZE);
        let data = &data[..end - start];
        // Process RAM: only inside an active sync manager's area.
        if end > RAM_START {
            return self.write_ram(start, data, t);
        }
        let touches = |register: usize, len: usize| start < register + len && end > register;
        // Latch the receive times before anything else (a write to 0x0900).
        if touches(reg::DC_RECEIVE_TIME_PORT0, 4) {
            self.latch_receive_times(t);
        }
        let system_time_written = touches(reg::DC_SYSTEM_TIME, 8);
        let old_activation = self.memory[reg::DC_ACTIVATION];
        for (offset, &byte) in data.iter().enumerate() {
            let address = start + offset;
            if is_writable_register(address) {
                self.memory[address] = byte;
            }
        }
        if system_time_written {
            self.system_time_written(start, data, t);
        }
        if touches(reg::AL_CONTROL, 2) {
            let control = read_u16(&self.memory, reg::AL_CONTROL).unwrap_or(0);
            self.al_control(control);
        }
        if touches(reg::SII_CONTROL, 2) {
            self.sii_command();
        }
        if touches(reg::DC_ACTIVATION, 1) && self.memory[reg::DC_ACTIVATION] != old_activation {
            self.next_sync0 = self
                .dc_sync_active()
                .then(|| read_u64(&self.memory, reg::DC_START_TIME).unwrap_or(0));
        }
        true
    }

    fn write_ram(&mut self, start: usize, data: &[u8], t: u64) -> bool {
        let end = start + data.len();
        let Some((n, sm)) = self.sm_at(start) else {
            return false;
        };
        let sm_start = usize::from(sm.start);
        let sm_end = sm_start + usize::from(sm.length);
        if end > sm_end || sm.master_reads() {
            return false;
        }
        self.memory[start..end].copy_from_slice(data);
        if end == sm_end {
            if sm.is_mailbox() {
                self.mailbox_request(n, t);
            } else {
                self.last_outputs_write = Some(self.system_time(t));
                if self.state >= AlState::SafeOp {
                    self.free_run_cycle(t);
                }
            }
        }
        true
    }

    fn mailbox_request(&mut self, sm_out: usize, _t: u64) {
        let Some(out) = self.sm(sm_out) else { return };
        let Some(sm_in) = (0..8).find_map(|n| {
            self.sm(n)
                .filter(|sm| sm.enabled && sm.is_mailbox() && sm.master_reads())
        }) else {
            return;
        };
        let request_start = usize::from(out.start);
        let request: Vec<u8> =
            self.memory[request_start..request_start + usize::from(out.length)].to_vec();
        let mut response = std::mem::take(&mut self.scratch_mailbox);
        response.clear();
        response.resize(usize::from(sm_in.length), 0);
        let answered = self.state >= AlState::PreOp
            && self.coe.handle(
                &request,
                &mut response,
                self.application.as_mut(),
                self.state,
            );
        if answered {
            if self.mailbox_in_full {
                self.pending_response = Some(response.clone());
            } else {
                self.put_response(&response);
            }
        }
        self.scratch_mailbox = response;
    }

    fn put_response(&mut self, response: &[u8]) {
        let Some(sm_in) = (0..8).find_map(|n| {
            self.sm(n)
                .filter(|sm| sm.enabled && sm.is_mailbox() && sm.master_reads())
        }) else {
            return;
        };
        let start = usize::from(sm_in.start);
        let len = usize::from(sm_in.length).min(response.len());
        if let Some(area) = self.memory.get_mut(start..start + len) {
            area.copy_from_slice(&response[..len]);
            self.mailbox_in_full = true;
        }
    }

    fn latch_receive_times(&mut self, t: u64) {
        let local_in = self.clock.local(t);
        write_u32(
            &mut self.memory,
            reg::DC_RECEIVE_TIME_PORT0,
            local_in as u32,
        );
        write_u64(&mut self.memory, reg::DC_RECEIVE_TIME_PU, local_in);
        // The frame comes back on port 1 after the devices downstream: latched when the
        // segment's walk knows when (`finish_frame`).
        self.return_latch_pending = self.has_downstream;
    }

    /// The end of a frame's walk: `t_return` is when it came back through port 1.
    pub(crate) fn finish_frame(&mut self, t_return: u64) {
        if self.return_latch_pending {
            self.return_latch_pending = false;
            let local = self.clock.local(t_return);
            write_u32(
                &mut self.memory,
                reg::DC_RECEIVE_TIME_PORT0 + 4,
                local as u32,
            );
        }
    }

    fn system_time_written(&mut self, start: usize, data: &[u8], t: u64) {
        // The value written, at the register's offset within the datagram.
        let offset = reg::DC_SYSTEM_TIME.saturating_sub(start);
        let skip = start.saturating_sub(reg::DC_SYSTEM_TIME);
        if skip > 0 {
            return;
        }
        let received = match data.len().saturating_sub(offset) {
            n if n >= 8 => read_u64(data, offset).unwrap_or(0),
            n if n >= 4 => u64::from(read_u32(data, offset).unwrap_or(0)),
            _ => return,
        };
        let delay = u64::from(read_u32(&self.memory, reg::DC_SYSTEM_TIME_DELAY).unwrap_or(0));
        let own = self.system_time(t);
        let difference = if data.len() - offset >= 8 {
            received.wrapping_add(delay).wrapping_sub(own) as i64
        } else {
            // A 32-bit write compares the low 32 bits only.
            (received.wrapping_add(delay) as u32).wrapping_sub(own as u32) as i32 as i64
        };
        let magnitude = difference.unsigned_abs().min(0x7FFF_FFFF) as u32;
        let sign = if difference > 0 { 0x8000_0000 } else { 0 };
        write_u32(
            &mut self.memory,
            reg::DC_SYSTEM_TIME_DIFFERENCE,
            magnitude | sign,
        );
        // The control loop: half the difference per write, at most a bounded step.
        self.drift_adjust_ns += (difference / 2).clamp(-DRIFT_STEP_LIMIT_NS, DRIFT_STEP_LIMIT_NS);
    }

    fn sii_command(&mut self) {
        let control = read_u16(&self.memory, reg::SII_CONTROL).unwrap_or(0);
        let address = read_u32(&self.memory, reg::SII_ADDRESS).unwrap_or(0);
        let mut errors = 0u16;
        match control & 0x0700 {
            0x0100 => {
                for n in 0..4u32 {
                    let word = self.sii.word(address.wrapping_add(n));
                    write_u16(&mut self.memory, reg::SII_DATA + 2 * n as usize, word);
                }
            }
            0x0200 => {
                let value = read_u16(&self.memory, reg::SII_DATA).unwrap_or(0);
                if control & 0x0001 == 0 || !self.sii.write_word(address, value) {
                    errors |= 0x2000; // command error
                }
            }
            0x0400 => {
                if !self.sii.header_crc_valid() {
                    errors |= 0x0800; // checksum error
                }
                write_u16(&mut self.memory, reg::STATION_ALIAS, self.sii.alias());
            }
            0 => {}
            _ => errors |= 0x2000,
        }
        let status = (control & 0x00FF) | 0x0040 | errors;
        write_u16(&mut self.memory, reg::SII_CONTROL, status);
    }

    fn al_control(&mut self, control: u16) {
        let acknowledge = control & 0x10 != 0;
        let requested = (control & 0x0F) as u8;
        if acknowledge {
            self.error = false;
            self.status_code = 0;
        }
        let Some(target) = AlState::from_bits(requested) else {
            self.refuse(al_code::UNKNOWN_STATE);
            return;
        };
        if self.error && !acknowledge && target > self.state {
            // An error stays until the master acknowledges it.
            return;
        }
        if target == AlState::Bootstrap {
            self.refuse(al_code::BOOTSTRAP_NOT_SUPPORTED);
            return;
        }
        if target == self.state {
            self.refresh_al_status();
            return;
        }
        if target < self.state {
            self.enter(target);
            return;
        }
        let next_allowed = match self.state {
            AlState::Init => AlState::PreOp,
            AlState::PreOp => AlState::SafeOp,
            AlState::SafeOp => AlState::Op,
            AlState::Op | AlState::Bootstrap => AlState::Op,
        };
        if target != next_allowed {
            self.refuse(al_code::INVALID_STATE_CHANGE);
            return;
        }
        let checked = match target {
            AlState::PreOp => self.check_mailbox_configuration(),
            AlState::SafeOp => self.check_process_data_configuration(),
            _ => Ok(()),
        };
        let context = self.transition_context();
        match checked.and_then(|()| self.application.check_transition(target, &context)) {
            Ok(()) => self.enter(target),
            Err(code) => self.refuse(code),
        }
    }

    fn transition_context(&self) -> TransitionContext {
        let length = |usage| {
            self.pd_sm(usage)
                .and_then(|n| self.sm(n))
                .filter(|sm| sm.enabled)
                .map_or(0, |sm| usize::from(sm.length))
        };
        TransitionContext {
            outputs_len: length(SyncManagerUse::Outputs),
            inputs_len: length(SyncManagerUse::Inputs),
            sync0_cycle_ns: self
                .dc_sync_active()
                .then(|| read_u32(&self.memory, reg::DC_SYNC0_CYCLE).unwrap_or(0)),
        }
    }

    fn check_mailbox_configuration(&self) -> Result<(), u16> {
        let Some(mailbox) = self.sii_contents.mailbox else {
            return Ok(());
        };
        let ok = |n: usize, start: u16, length: u16| {
            self.sm(n)
                .is_some_and(|sm| sm.enabled && sm.start == start && sm.length == length)
        };
        if ok(0, mailbox.receive_offset, mailbox.receive_size)
            && ok(1, mailbox.send_offset, mailbox.send_size)
        {
            Ok(())
        } else {
            Err(al_code::INVALID_MAILBOX_CONFIGURATION)
        }
    }

    fn check_process_data_configuration(&self) -> Result<(), u16> {
        let (out_len, in_len) = self.application.process_data_len();
        let matches = |len: usize, usage| {
            let Some(n) = self.pd_sm(usage) else {
                return len == 0;
            };
            let Some(sm) = self.sm(n) else {
                return len == 0;
            };
            if len == 0 {
                return !sm.enabled || sm.length == 0;
            }
            let default_start = self.sii_contents.sync_managers[n].start;
            sm.enabled && usize::from(sm.length) == len && sm.start == default_start
        };
        if !matches(out_len, SyncManagerUse::Outputs) {
            return Err(al_code::INVALID_OUTPUT_CONFIGURATION);
        }
        if !matches(in_len, SyncManagerUse::Inputs) {
            return Err(al_code::INVALID_INPUT_CONFIGURATION);
        }
        Ok(())
    }

    fn enter(&mut self, state: AlState) {
        if state <= AlState::PreOp {
            self.last_outputs_write = None;
            self.last_free_run = None;
        }
        if state == AlState::Init {
            self.coe = CoeServer::new();
            self.mailbox_in_full = false;
            self.pending_response = None;
        }
        if state == AlState::SafeOp && self.state == AlState::Op {
            // Outputs stop being applied: one cycle with outputs invalid.
            let at = self.next_sync0.or(self.last_free_run).unwrap_or(0);
            self.run_cycle(1e-3, at);
        }
        self.state = state;
        self.refresh_al_status();
    }

    fn refuse(&mut self, code: u16) {
        self.error = true;
        self.status_code = code;
        self.refresh_al_status();
    }

    /// A logical access: the FMMUs map `data` (the datagram's bytes at logical `address`)
    /// onto physical memory. Returns the working-counter increment: 1 for a read, 2 for a
    /// write, as the command allows.
    pub fn logical(&mut self, command: Command, address: u32, data: &mut [u8], t: u64) -> u16 {
        let reads = matches!(command, Command::Lrd | Command::Lrw);
        let writes = matches!(command, Command::Lwr | Command::Lrw);
        let mut read_hit = false;
        let mut write_hit = false;
        let mut outputs_complete = false;
        // Writes first: they take the master's bytes before a read FMMU on the same logical
        // bytes replaces them.
        for pass_write in [true, false] {
            if (pass_write && !writes) || (!pass_write && !reads) {
                continue;
            }
            for n in 0..8 {
                let Some(fmmu) = self.fmmu(n) else { continue };
                if !fmmu.enabled || (pass_write && !fmmu.write) || (!pass_write && !fmmu.read) {
                    continue;
                }
                let (hit, completes) = self.map_fmmu(&fmmu, address, data, pass_write);
                if pass_write {
                    write_hit |= hit;
                    outputs_complete |= completes;
                } else {
                    read_hit |= hit;
                }
            }
        }
        if outputs_complete {
            self.last_outputs_write = Some(self.system_time(t));
            if self.state >= AlState::SafeOp {
                self.free_run_cycle(t);
            }
        }
        u16::from(read_hit) + 2 * u16::from(write_hit)
    }

    fn fmmu(&self, n: usize) -> Option<Fmmu> {
        let base = reg::FMMU + 16 * n;
        let b = self.memory.get(base..base + 16)?;
        Some(Fmmu {
            logical_start: u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            length: u16::from_le_bytes([b[4], b[5]]),
            logical_start_bit: b[6] & 0x07,
            logical_end_bit: b[7] & 0x07,
            physical_start: u16::from_le_bytes([b[8], b[9]]),
            physical_start_bit: b[10] & 0x07,
            read: b[11] & 0x01 != 0,
            write: b[11] & 0x02 != 0,
            enabled: b[12] & 0x01 != 0,
        })
    }

    /// Moves the bits one FMMU maps between the datagram and memory. Returns whether any
    /// byte was mapped and whether a write reached the last byte of its sync manager.
    fn map_fmmu(
        &mut self,
        fmmu: &Fmmu,
        address: u32,
        data: &mut [u8],
        write: bool,
    ) -> (bool, bool) {
        if fmmu.length == 0 {
            return (false, false);
        }
        // Logical bit range of the FMMU, inclusive.
        let first_bit = u64::from(fmmu.logical_start) * 8 + u64::from(fmmu.logical_start_bit);
        let last_bit = (u64::from(fmmu.logical_start) + u64::from(fmmu.length) - 1) * 8
            + u64::from(fmmu.logical_end_bit);
        if last_bit < first_bit {
            return (false, false);
        }
        let datagram_first = u64::from(address) * 8;
        let datagram_last = datagram_first + data.len() as u64 * 8;
        let from = first_bit.max(datagram_first);
        let to = (last_bit + 1).min(datagram_last);
        if from >= to {
            return (false, false);
        }
        let physical_base = u64::from(fmmu.physical_start) * 8 + u64::from(fmmu.physical_start_bit);
        let physical_from = physical_base + (from - first_bit);
        let physical_to = physical_base + (to - first_bit);
        // The physical bytes must lie in one active sync manager of the right direction.
        let first_byte = (physical_from / 8) as usize;
        let last_byte = ((physical_to - 1) / 8) as usize;
        let Some((_, sm)) = self.sm_at(first_byte) else {
            return (false, false);
        };
        let sm_end = usize::from(sm.start) + usize::from(sm.length);
        if last_byte >= sm_end || sm.is_mailbox() || sm.master_reads() == write {
            return (false, false);
        }
        let aligned = from % 8 == 0 && to % 8 == 0 && physical_from % 8 == 0;
        let datagram_from = ((from - datagram_first) / 8) as usize;
        if aligned {
            let len = ((to - from) / 8) as usize;
            let memory = &mut self.memory[first_byte..first_byte + len];
            let datagram = &mut data[datagram_from..datagram_from + len];
            if write {
                memory.copy_from_slice(datagram);
            } else {
                datagram.copy_from_slice(memory);
            }
        } else {
            for k in 0..(to - from) {
                let logical_bit = from + k - datagram_first;
                let physical_bit = physical_from + k;
                let (lb, lbit) = ((logical_bit / 8) as usize, (logical_bit % 8) as u8);
                let (pb, pbit) = ((physical_bit / 8) as usize, (physical_bit % 8) as u8);
                if write {
                    let value = (data[lb] >> lbit) & 1;
                    self.memory[pb] = (self.memory[pb] & !(1 << pbit)) | (value << pbit);
                } else {
                    let value = (self.memory[pb] >> pbit) & 1;
                    data[lb] = (data[lb] & !(1 << lbit)) | (value << lbit);
                }
            }
        }
        (true, write && last_byte + 1 == sm_end)
    }

    /// The configured station address.
    pub fn station_address(&self) -> u16 {
        read_u16(&self.memory, reg::STATION_ADDRESS).unwrap_or(0)
    }

    /// Processes one datagram at this device. `addressing` says whether the device is the
    /// addressed one (for physical commands other than broadcasts); returns the working
    /// counter increment.
    pub fn datagram(
        &mut self,
        command: Command,
        addressing: Addressing,
        address: u32,
        data: &mut [u8],
        t: u64,
    ) -> u16 {
        let offset = (address >> 16) as u16;
        let addressed = addressing == Addressing::Addressed;
        match command {
            Command::Nop => 0,
            Command::Aprd | Command::Fprd if addressed => {
                u16::from(self.read(offset, data, false, t))
            }
            Command::Apwr | Command::Fpwr if addressed => u16::from(self.write(offset, data, t)),
            Command::Aprw | Command::Fprw if addressed => self.read_write(offset, data, false, t),
            Command::Brd => u16::from(self.read(offset, data, true, t)),
            Command::Bwr => u16::from(self.write(offset, data, t)),
            Command::Brw => self.read_write(offset, data, true, t),
            Command::Armw | Command::Frmw => {
                if addressed {
                    u16::from(self.read(offset, data, false, t))
                } else {
                    u16::from(self.write(offset, data, t))
                }
            }
            Command::Lrd | Command::Lwr | Command::Lrw => self.logical(command, address, data, t),
            _ => 0,
        }
    }

    fn read_write(&mut self, offset: u16, data: &mut [u8], or: bool, t: u64) -> u16 {
        let mut written = [0u8; 1536];
        let len = data.len().min(written.len());
        written[..len].copy_from_slice(&data[..len]);
        let read = self.read(offset, data, or, t);
        let wrote = self.write(offset, &written[..len], t);
        u16::from(read) + 2 * u16::from(wrote)
    }
}

/// Whether the master may write this register byte (identity, status and computed
/// registers are read-only).
fn is_writable_register(address: usize) -> bool {
    match address {
        0x0010..=0x0013 => true, // station address and alias
        0x0100..=0x0103 => true, // DL control
        0x0120..=0x0121 => true, // AL control
        0x0200..=0x0205 => true, // event masks
        0x0300..=0x0313 => true, // error counters (cleared by writing)
        0x0400..=0x0401 | 0x0410..=0x0411 | 0x0420..=0x0421 => true, // watchdogs
        0x0500 | 0x0502..=0x050F => true, // SII interface
        0x0600..=0x06FF => true, // FMMUs
        0x0800..=0x087F => address % 8 != 5 && address % 8 != 7, // SMs except status bytes
        0x0900..=0x0903 => false, // receive time latch: a write only triggers it
        0x0910..=0x0917 => false, // system time: handled as a DC write
        0x0920..=0x092B => true, // offset and delay
        0x0930..=0x0935 => true, // DC control loop parameters
        0x0980..=0x0983 => true, // cyclic unit control, activation, pulse
        0x0990..=0x0997 => true, // start time
        0x09A0..=0x09A7 => true, // SYNC0/SYNC1 cycle times
        _ => false,
    }
}

/// The registers of one sync manager.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct SyncManagerRegs {
    start: u16,
    length: u16,
    control: u8,
    enabled: bool,
}

impl SyncManagerRegs {
    /// Control bits 0-1: 0b10 mailbox, 0b00 three-buffer.
    fn is_mailbox(&self) -> bool {
        self.control & 0x03 == 0x02
    }
    /// Control bits 2-3: 0b00 the master reads (ECAT read), 0b01 the master writes.
    fn master_reads(&self) -> bool {
        self.control & 0x0C == 0x00
    }
}

/// The registers of one FMMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Fmmu {
    logical_start: u32,
    length: u16,
    logical_start_bit: u8,
    logical_end_bit: u8,
    physical_start: u16,
    physical_start_bit: u8,
    read: bool,
    write: bool,
    enabled: bool,
}
