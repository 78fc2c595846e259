//! Touch probe 1 of a CiA 402 drive (IEC 61800-7-201 / CiA 402, ETG.6010): the function
//! the master writes (0x60B8), the status it reads back (0x60B9) and the positions latched
//! at the trigger's positive and negative edges (0x60BA, 0x60BB).
//!
//! Bits as CiA 402 defines them and drives document them (Panasonic's touch probe notes in
//! RSI's RapidCode example "TouchProbe.cs"; Beckhoff EP7211 "Touch Probe", AX8000 object
//! 0x60B8/0x60B9 pages): 0x60B8 bit 0 enables probe 1, bit 1 continuous (else the first
//! event only), bits 2-3 the trigger (00 the probe input, 01 the encoder's zero impulse;
//! 10 the source in 0x60D0 and 11 reserved are not offered here), bit 4 samples the
//! positive edge, bit 5 the negative one. 0x60B9 bit 0 probe 1 enabled, bit 1 a
//! positive-edge value stored, bit 2 a negative-edge value stored; bits 6 and 7, user
//! defined in CiA 402, toggle with every new positive and negative value (the way ETG.6010
//! drives let a master see a new value in continuous mode; not checked against ETG.6010's
//! text, which is not public).
//!
//! Edges count from the cycle in which their sampling bit was set; a single-event probe
//! takes the first one and then none until its sampling bit (or the enable) goes off and on
//! again, which also clears the stored bit. Disabling the probe clears bits 0-2; the
//! toggle bits keep their level (a master compares them with the last it saw).

/// Bits of 0x60B8, touch probe function.
pub mod function {
    /// Touch probe 1 enabled.
    pub const ENABLE: u16 = 1 << 0;
    /// Continuous: every event; else the first one only.
    pub const CONTINUOUS: u16 = 1 << 1;
    /// Trigger selection (bits 2-3).
    pub const TRIGGER_MASK: u16 = 0b11 << 2;
    /// Trigger on the touch probe 1 input.
    pub const TRIGGER_INPUT: u16 = 0b00 << 2;
    /// Trigger on the position encoder's zero impulse (index).
    pub const TRIGGER_INDEX: u16 = 0b01 << 2;
    /// Sample at the positive edge (value to 0x60BA).
    pub const POSITIVE_EDGE: u16 = 1 << 4;
    /// Sample at the negative edge (value to 0x60BB).
    pub const NEGATIVE_EDGE: u16 = 1 << 5;
}

/// Bits of 0x60B9, touch probe status.
pub mod status {
    /// Touch probe 1 is enabled.
    pub const ENABLED: u16 = 1 << 0;
    /// A positive-edge value is stored in 0x60BA.
    pub const POSITIVE_STORED: u16 = 1 << 1;
    /// A negative-edge value is stored in 0x60BB.
    pub const NEGATIVE_STORED: u16 = 1 << 2;
    /// Toggles with every new positive-edge value.
    pub const POSITIVE_TOGGLE: u16 = 1 << 6;
    /// Toggles with every new negative-edge value.
    pub const NEGATIVE_TOGGLE: u16 = 1 << 7;
}

/// What triggers the probe.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trigger {
    /// The touch probe 1 input (a wire into the drive).
    Input,
    /// The encoder's zero impulse.
    IndexPulse,
}

/// A value caught and not yet reported: which edge (0 positive, 1 negative), the encoder
/// increments, and when it is reported (system time, ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Report {
    edge: usize,
    counts: i32,
    due_ns: u64,
}

/// Largest number of input edges waiting for the drive's position at their instant, and
/// of values caught and not yet reported.
const QUEUE: usize = 8;

/// Touch probe 1.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TouchProbe {
    function: u16,
    status: u16,
    values: [i32; 2],
    /// Per edge (positive, negative): sampled from this system time on.
    armed_since: [Option<u64>; 2],
    /// Per edge: a single-event probe has taken its event.
    caught: [bool; 2],
    reports: [Option<Report>; QUEUE],
    /// Input edges (instant, positive) waiting for the position at their instant.
    edges: [Option<(u64, bool)>; QUEUE],
    latency_ns: u64,
}

const STORED: [u16; 2] = [status::POSITIVE_STORED, status::NEGATIVE_STORED];
const TOGGLE: [u16; 2] = [status::POSITIVE_TOGGLE, status::NEGATIVE_TOGGLE];
const SAMPLE: [u16; 2] = [function::POSITIVE_EDGE, function::NEGATIVE_EDGE];

impl TouchProbe {
    /// A probe off, reporting a caught value `latency_ns` after its edge.
    pub fn new(latency_ns: u64) -> Self {
        Self {
            function: 0,
            status: 0,
            values: [0; 2],
            armed_since: [None; 2],
            caught: [false; 2],
            reports: [None; QUEUE],
            edges: [None; QUEUE],
            latency_ns,
        }
    }

    /// The function the master wrote (0x60B8), in force from the cycle starting at `now_ns`.
    pub fn command(&mut self, function: u16, now_ns: u64) {
        let old = self.function;
        self.function = function;
        if function & function::ENABLE == 0 {
            self.status &= !(status::ENABLED | STORED[0] | STORED[1]);
            self.armed_since = [None; 2];
            self.caught = [false; 2];
            self.reports = [None; QUEUE];
            self.edges = [None; QUEUE];
            return;
        }
        // A new enable, mode or trigger starts both edges afresh.
        let restart = old & function::ENABLE == 0
            || (old ^ function) & (function::CONTINUOUS | function::TRIGGER_MASK) != 0;
        self.status |= status::ENABLED;
        for edge in 0..2 {
            let on = function & SAMPLE[edge] != 0;
            let was_on = !restart && old & SAMPLE[edge] != 0;
            if on && was_on {
                continue;
            }
            self.armed_since[edge] = on.then_some(now_ns);
            self.caught[edge] = false;
            self.status &= !STORED[edge];
            for slot in &mut self.reports {
                if slot.is_some_and(|r| r.edge == edge) {
                    *slot = None;
                }
            }
        }
    }

    /// What triggers the probe while it is enabled (`None`: off, or a trigger not offered).
    pub fn trigger(&self) -> Option<Trigger> {
        if self.function & function::ENABLE == 0 {
            return None;
        }
        match self.function & function::TRIGGER_MASK {
            function::TRIGGER_INPUT => Some(Trigger::Input),
            function::TRIGGER_INDEX => Some(Trigger::IndexPulse),
            _ => None,
        }
    }

    /// Whether an edge (`positive` or not) at `at_ns` would be caught now.
    pub fn takes(&self, positive: bool, at_ns: u64) -> bool {
        let edge = usize::from(!positive);
        self.armed_since[edge].is_some_and(|since| at_ns >= since)
            && (self.function & function::CONTINUOUS != 0 || !self.caught[edge])
    }

    /// The trigger's edge at `at_ns`, the encoder at `counts` then: caught if the probe
    /// samples it, reported `latency` after the edge.
    pub fn latch(&mut self, positive: bool, at_ns: u64, counts: i32) {
        if !self.takes(positive, at_ns) {
            return;
        }
        let edge = usize::from(!positive);
        self.caught[edge] = true;
        let report = Report {
            edge,
            counts,
            due_ns: at_ns.saturating_add(self.latency_ns),
        };
        // A full queue (continuous edges faster than the latency) drops the oldest.
        let slot = match self.reports.iter().position(Option::is_none) {
            Some(free) => free,
            None => {
                self.reports.rotate_left(1);
                QUEUE - 1
            }
        };
        self.reports[slot] = Some(report);
    }

    /// An edge of the touch probe input at `at_ns`; it waits for [`resolve`](Self::resolve)
    /// to know the position then.
    pub fn input_edge(&mut self, at_ns: u64, positive: bool) {
        if self.trigger() != Some(Trigger::Input) || !self.takes(positive, at_ns) {
            return;
        }
        match self.edges.iter_mut().find(|e| e.is_none()) {
            Some(slot) => *slot = Some((at_ns, positive)),
            None => {
                self.edges.rotate_left(1);
                self.edges[QUEUE - 1] = Some((at_ns, positive));
            }
        }
    }

    /// Latches the waiting input edges whose position `counts_at` knows (in time order);
    /// the others wait.
    pub fn resolve(&mut self, counts_at: impl Fn(u64) -> Option<i32>) {
        self.edges
            .sort_unstable_by_key(|e| e.map_or(u64::MAX, |(at, _)| at));
        for n in 0..QUEUE {
            if let Some((at, positive)) = self.edges[n]
                && let Some(counts) = counts_at(at)
            {
                self.edges[n] = None;
                self.latch(positive, at, counts);
            }
        }
    }

    /// Reports the values due by `now_ns`: the value object, its stored bit, its toggle.
    pub fn report(&mut self, now_ns: u64) {
        self.reports
            .sort_unstable_by_key(|r| r.map_or(u64::MAX, |r| r.due_ns));
        for slot in &mut self.reports {
            if let Some(r) = *slot
                && r.due_ns <= now_ns
            {
                self.values[r.edge] = r.counts;
                self.status |= STORED[r.edge];
                self.status ^= TOGGLE[r.edge];
                *slot = None;
            }
        }
    }

    /// 0x60B9.
    pub fn status(&self) -> u16 {
        self.status
    }

    /// 0x60BA: the position (increments) at the last positive edge reported.
    pub fn positive_value(&self) -> i32 {
        self.values[0]
    }

    /// 0x60BB: the position (increments) at the last negative edge reported.
    pub fn negative_value(&self) -> i32 {
        self.values[1]
    }
}
