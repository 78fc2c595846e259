//! The client's side of the link (the API server): attach, send commands and urgent
//! commands, read the status, drain events, trace and replies, beat the heartbeat. One
//! client per machine; inside the client process, a lock keeps each ring single-producer
//! and single-consumer.

use std::sync::Mutex;
use std::sync::atomic::Ordering;

use super::layout::{
    self, ServiceReply, ServiceRequest, TraceSample, WireCommand, WireEvent, WireStatus,
    WireTiming, WireUrgent, WireWatch,
};
use super::segment::{LinkError, Mapping, monotonic_ns};

/// Why a client call did not go through.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ClientError {
    /// The ring is full: the machine does not read it (it is gone or stalled).
    #[error("the machine's command ring is full")]
    Full,
}

/// An attached client.
pub struct Client {
    map: Mapping,
    /// Serialises the rings this process produces into.
    produce: Mutex<()>,
    /// Serialises the rings this process consumes from.
    consume: Mutex<()>,
    pid: u32,
}

fn process_alive(pid: u32) -> bool {
    let Ok(pid) = i32::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks that the process exists.
    pid > 0 && unsafe { libc::kill(pid, 0) } == 0
}

impl Client {
    /// Maps the machine's segment `name` and becomes its client; refused while another
    /// live process is attached.
    pub fn attach(name: &str) -> Result<Client, LinkError> {
        let map = Mapping::open(name)?;
        let pid = std::process::id();
        let seg = map.segment();
        let holder = seg.client_pid.load(Ordering::Acquire);
        if holder != 0 && holder != pid && process_alive(holder) {
            return Err(LinkError::Busy(holder));
        }
        seg.client_heartbeat.fetch_add(1, Ordering::AcqRel);
        let _ = seg
            .client_pid
            .compare_exchange(holder, pid, Ordering::AcqRel, Ordering::Relaxed);
        Ok(Client {
            map,
            produce: Mutex::new(()),
            consume: Mutex::new(()),
            pid,
        })
    }

    /// The mapping.
    pub fn mapping(&self) -> &Mapping {
        &self.map
    }

    /// The header.
    pub fn header(&self) -> &layout::Header {
        &self.map.segment().header
    }

    /// The machine's name.
    pub fn machine_name(&self) -> &str {
        layout::field_name(&self.header().machine_name)
    }

    /// A joint's name.
    pub fn joint_name(&self, joint: usize) -> &str {
        self.header()
            .joint_names
            .get(joint)
            .map_or("", |n| layout::field_name(n))
    }

    /// Beats the client's heartbeat; claims the machine again if it declared this client
    /// lost (a stall). False when another client has taken the machine over.
    pub fn heartbeat(&self) -> bool {
        let seg = self.map.segment();
        seg.client_heartbeat.fetch_add(1, Ordering::AcqRel);
        match seg.client_pid.load(Ordering::Acquire) {
            p if p == self.pid => true,
            0 => seg
                .client_pid
                .compare_exchange(0, self.pid, Ordering::AcqRel, Ordering::Relaxed)
                .is_ok(),
            _ => false,
        }
    }

    /// The machine's heartbeat (its servo cycle); it stands still when the machine is gone.
    pub fn machine_heartbeat(&self) -> u64 {
        self.map.segment().machine_heartbeat.load(Ordering::Acquire)
    }

    /// The start of the machine this segment belongs to.
    pub fn instance(&self) -> u64 {
        self.header().instance
    }

    /// The newest status snapshot.
    pub fn status(&self) -> WireStatus {
        self.map.segment().status.read()
    }

    /// Task timing.
    pub fn timing(&self) -> WireTiming {
        self.map.segment().timing.read()
    }

    /// Watched PLC values.
    pub fn watch(&self) -> WireWatch {
        self.map.segment().watch.read()
    }

    /// Sends a normal command.
    pub fn send(&self, mut command: WireCommand) -> Result<(), ClientError> {
        command.written_ns = monotonic_ns();
        let _guard = self.produce.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: pushes are serialised by `produce`; this process is the one client.
        unsafe { self.map.segment().commands.push(command) }.map_err(|_| ClientError::Full)
    }

    /// Sends an urgent command, stamped with the time and the machine's cycle.
    pub fn send_urgent(&self, mut command: WireUrgent) -> Result<(), ClientError> {
        let _guard = self.produce.lock().unwrap_or_else(|e| e.into_inner());
        command.written_cycle = self.machine_heartbeat();
        command.written_ns = monotonic_ns();
        // SAFETY: as in `send`.
        unsafe { self.map.segment().urgent.push(command) }.map_err(|_| ClientError::Full)
    }

    /// Sends a request to the machine's service thread.
    pub fn request(&self, request: ServiceRequest) -> Result<(), ClientError> {
        let _guard = self.produce.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: as in `send`.
        unsafe { self.map.segment().requests.push(request) }.map_err(|_| ClientError::Full)
    }

    /// Hands every waiting event to `f`, oldest first.
    pub fn drain_events(&self, mut f: impl FnMut(WireEvent)) {
        let _guard = self.consume.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: pops are serialised by `consume`; this process is the one client.
        while let Some(e) = unsafe { self.map.segment().events.pop() } {
            f(e);
        }
    }

    /// Hands every waiting trace sample to `f`.
    pub fn drain_trace(&self, mut f: impl FnMut(&TraceSample)) {
        let _guard = self.consume.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: as in `drain_events`.
        while let Some(s) = unsafe { self.map.segment().trace.pop() } {
            f(&s);
        }
    }

    /// Hands every waiting service reply to `f`.
    pub fn drain_replies(&self, mut f: impl FnMut(ServiceReply)) {
        let _guard = self.consume.lock().unwrap_or_else(|e| e.into_inner());
        // SAFETY: as in `drain_events`.
        while let Some(r) = unsafe { self.map.segment().replies.pop() } {
            f(r);
        }
    }

    /// Whether the segment's name still leads to this machine (a restarted machine makes
    /// a new segment under the same name).
    pub fn is_current(&self, name: &str) -> bool {
        Mapping::open(name).is_ok_and(|m| m.segment().header.instance == self.instance())
    }

    /// Leaves the machine (a clean exit; a killed client is found by its heartbeat).
    pub fn detach(&self) {
        let seg = self.map.segment();
        if seg
            .client_pid
            .compare_exchange(self.pid, 0, Ordering::AcqRel, Ordering::Relaxed)
            .is_ok()
        {
            seg.client_detaches.fetch_add(1, Ordering::AcqRel);
        }
    }
}
