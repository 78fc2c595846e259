//! Where the master's frames go: a network interface (raw socket), or a simulated segment
//! in the same process.

use std::io;
use std::sync::Arc;
use std::time::Duration;

use rtcnc_ecat_slave_sim::raw_socket::RawSocket;
use rtcnc_ecat_slave_sim::{Outcome, Segment};
use rtcnc_rt::PiMutex;

use crate::clock::Clock;

/// Largest Ethernet frame handled (bytes).
pub const MAX_FRAME: usize = 1536;

/// A port that sends EtherCAT frames and receives the replies.
pub trait Link: Send {
    /// Sends one Ethernet frame.
    fn send(&mut self, frame: &[u8]) -> io::Result<()>;
    /// The next received frame, waiting at most `timeout`; `Ok(None)` when none came.
    fn receive(&mut self, buffer: &mut [u8], timeout: Duration) -> io::Result<Option<usize>>;
    /// Whether the link (the cable) is up.
    fn is_up(&mut self) -> bool;
    /// The interface's name, for messages.
    fn name(&self) -> &str;
    /// Whether a reply, if any, is there as soon as its frame is sent (a simulated
    /// segment), so that waiting longer for a missing one is pointless.
    fn replies_at_once(&self) -> bool {
        false
    }
}

/// A network interface through a raw socket.
#[derive(Debug)]
pub struct NetworkLink {
    socket: RawSocket,
}

impl NetworkLink {
    /// Opens `interface` (needs CAP_NET_RAW).
    pub fn open(interface: &str) -> io::Result<Self> {
        Ok(Self {
            socket: RawSocket::open(interface)?,
        })
    }
}

impl Link for NetworkLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.socket.send(frame)
    }

    fn receive(&mut self, buffer: &mut [u8], timeout: Duration) -> io::Result<Option<usize>> {
        self.socket.receive(buffer, Some(timeout))
    }

    fn is_up(&mut self) -> bool {
        self.socket.link_up()
    }

    fn name(&self) -> &str {
        self.socket.interface()
    }
}

/// Replies held between `send` and `receive`.
const QUEUE: usize = 16;

/// A simulated segment in the same process: each frame is processed when sent, at the
/// clock's time, and its reply is queued. Deterministic under a virtual clock.
pub struct SimulatedLink {
    segment: Arc<PiMutex<Segment>>,
    clock: Clock,
    slots: Vec<[u8; MAX_FRAME]>,
    lengths: [usize; QUEUE],
    head: usize,
    count: usize,
}

impl std::fmt::Debug for SimulatedLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimulatedLink")
            .field("queued", &self.count)
            .finish_non_exhaustive()
    }
}

impl SimulatedLink {
    /// A link to `segment`, frames arriving at `clock`'s time.
    pub fn new(segment: Arc<PiMutex<Segment>>, clock: Clock) -> Self {
        Self {
            segment,
            clock,
            slots: vec![[0u8; MAX_FRAME]; QUEUE],
            lengths: [0; QUEUE],
            head: 0,
            count: 0,
        }
    }
}

impl Link for SimulatedLink {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        if frame.len() > MAX_FRAME {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "frame too long",
            ));
        }
        if self.count == QUEUE {
            // A full queue drops the oldest reply, as a NIC ring would.
            self.head = (self.head + 1) % QUEUE;
            self.count -= 1;
        }
        let slot = (self.head + self.count) % QUEUE;
        let buffer = &mut self.slots[slot][..frame.len()];
        buffer.copy_from_slice(frame);
        let outcome = self
            .segment
            .lock()
            .process(buffer, self.clock.now_ns())
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))?;
        if outcome == Outcome::Returned {
            self.lengths[slot] = frame.len();
            self.count += 1;
        }
        Ok(())
    }

    fn receive(&mut self, buffer: &mut [u8], _timeout: Duration) -> io::Result<Option<usize>> {
        if self.count == 0 {
            return Ok(None);
        }
        let slot = self.head;
        let len = self.lengths[slot].min(buffer.len());
        buffer[..len].copy_from_slice(&self.slots[slot][..len]);
        self.head = (self.head + 1) % QUEUE;
        self.count -= 1;
        Ok(Some(len))
    }

    fn is_up(&mut self) -> bool {
        self.segment.lock().link_up()
    }

    fn name(&self) -> &str {
        "simulated"
    }

    fn replies_at_once(&self) -> bool {
        true
    }
}
