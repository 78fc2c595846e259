//! A raw Ethernet port on a network interface (Linux `AF_PACKET`), for EtherCAT frames
//! only: what both the simulator process and the master's network link stand on.
//!
//! Opening one needs CAP_NET_RAW (root, or a user namespace that owns the network
//! namespace). Frames this socket sends are not received back on it
//! (`PACKET_IGNORE_OUTGOING`), so neither side sees its own frames.

use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::time::Duration;

use crate::frame::ETHERTYPE;

/// `PACKET_IGNORE_OUTGOING` (linux/if_packet.h), not in every libc release.
const PACKET_IGNORE_OUTGOING: libc::c_int = 23;

/// An open raw socket bound to one interface.
#[derive(Debug)]
pub struct RawSocket {
    fd: OwnedFd,
    interface: String,
    name: CString,
}

fn check(result: libc::c_int) -> io::Result<libc::c_int> {
    if result < 0 {
        Err(io::Error::last_os_error())
    } else {
        Ok(result)
    }
}

impl RawSocket {
    /// Opens the interface for EtherCAT frames.
    pub fn open(interface: &str) -> io::Result<Self> {
        let name = CString::new(interface)
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "interface name"))?;
        // SAFETY: plain syscalls on values we own; the fd is checked before use.
        let fd = check(unsafe {
            libc::socket(
                libc::AF_PACKET,
                libc::SOCK_RAW | libc::SOCK_NONBLOCK | libc::SOCK_CLOEXEC,
                i32::from(ETHERTYPE.to_be()),
            )
        })?;
        // SAFETY: `fd` is a new descriptor nobody else owns.
        let fd = unsafe { OwnedFd::from_raw_fd(fd) };
        // SAFETY: `name` is NUL-terminated.
        let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if index == 0 {
            return Err(io::Error::last_os_error());
        }
        // SAFETY: zeroed sockaddr_ll is valid; the fields are set below.
        let mut address: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        address.sll_family = libc::AF_PACKET as u16;
        address.sll_protocol = ETHERTYPE.to_be();
        address.sll_ifindex = index as i32;
        // SAFETY: the address is a valid sockaddr_ll of the given size.
        check(unsafe {
            libc::bind(
                fd.as_raw_fd(),
                (&raw const address).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        })?;
        let one: libc::c_int = 1;
        // Older kernels lack the option; the master and simulator also filter by source.
        // SAFETY: the option value is a valid c_int.
        let _ = unsafe {
            libc::setsockopt(
                fd.as_raw_fd(),
                libc::SOL_PACKET,
                PACKET_IGNORE_OUTGOING,
                (&raw const one).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        Ok(Self {
            fd,
            interface: interface.to_owned(),
            name,
        })
    }

    /// The interface's name.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// Sends one frame.
    pub fn send(&self, frame: &[u8]) -> io::Result<()> {
        // SAFETY: the buffer is valid for its length.
        let sent =
            unsafe { libc::send(self.fd.as_raw_fd(), frame.as_ptr().cast(), frame.len(), 0) };
        if sent < 0 {
            return Err(io::Error::last_os_error());
        }
        if sent as usize != frame.len() {
            return Err(io::Error::new(io::ErrorKind::WriteZero, "frame cut short"));
        }
        Ok(())
    }

    /// The next frame into `buffer`, waiting at most `timeout` (`None`: forever); `Ok(None)`
    /// when none came in time.
    pub fn receive(
        &self,
        buffer: &mut [u8],
        timeout: Option<Duration>,
    ) -> io::Result<Option<usize>> {
        loop {
            // SAFETY: the buffer is valid for its length; MSG_DONTWAIT never blocks.
            let received = unsafe {
                libc::recv(
                    self.fd.as_raw_fd(),
                    buffer.as_mut_ptr().cast(),
                    buffer.len(),
                    libc::MSG_DONTWAIT,
                )
            };
            if received >= 0 {
                return Ok(Some(received as usize));
            }
            let error = io::Error::last_os_error();
            if error.kind() != io::ErrorKind::WouldBlock {
                return Err(error);
            }
            if !self.wait_readable(timeout)? {
                return Ok(None);
            }
        }
    }

    /// Waits until a frame can be read, at most `timeout`; returns whether one can.
    fn wait_readable(&self, timeout: Option<Duration>) -> io::Result<bool> {
        let mut poll = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let spec = timeout.map(|t| libc::timespec {
            tv_sec: t.as_secs().min(i64::MAX as u64) as libc::time_t,
            tv_nsec: libc::c_long::from(t.subsec_nanos() as i32),
        });
        let spec_ptr = spec
            .as_ref()
            .map_or(std::ptr::null(), |s| s as *const libc::timespec);
        // SAFETY: one valid pollfd; the timespec outlives the call.
        let ready = unsafe { libc::ppoll(&raw mut poll, 1, spec_ptr, std::ptr::null()) };
        if ready < 0 {
            let error = io::Error::last_os_error();
            if error.kind() == io::ErrorKind::Interrupted {
                return Ok(false);
            }
            return Err(error);
        }
        Ok(ready > 0)
    }

    /// Whether the interface is up with a carrier (the cable is in).
    pub fn link_up(&self) -> bool {
        self.flags()
            .is_ok_and(|f| f & libc::IFF_UP as i16 != 0 && f & libc::IFF_RUNNING as i16 != 0)
    }

    fn flags(&self) -> io::Result<i16> {
        // SAFETY: zeroed ifreq is valid; the name fits (checked below).
        let mut request: libc::ifreq = unsafe { std::mem::zeroed() };
        let bytes = self.name.as_bytes();
        if bytes.len() >= request.ifr_name.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "interface name",
            ));
        }
        for (d, s) in request.ifr_name.iter_mut().zip(bytes) {
            *d = *s as libc::c_char;
        }
        // SAFETY: SIOCGIFFLAGS fills the ifreq we own.
        check(unsafe { libc::ioctl(self.fd.as_raw_fd(), libc::SIOCGIFFLAGS, &raw mut request) })?;
        // SAFETY: the kernel filled the flags member of the union.
        Ok(unsafe { request.ifr_ifru.ifru_flags })
    }

    /// Takes the interface up or down (needs CAP_NET_ADMIN): how the simulator pulls its
    /// cable.
    pub fn set_up(&self, up: bool) -> io::Result<()> {
        let mut flags = self.flags()?;
        if up {
            flags |= libc::IFF_UP as i16;
        } else {
            flags &= !(libc::IFF_UP as i16);
        }
        // SAFETY: as in `flags`.
        let mut request: libc::ifreq = unsafe { std::mem::zeroed() };
        for (d, s) in request.ifr_name.iter_mut().zip(self.name.as_bytes()) {
            *d = *s as libc::c_char;
        }
        request.ifr_ifru.ifru_flags = flags;
        // SAFETY: SIOCSIFFLAGS reads the ifreq we own.
        check(unsafe { libc::ioctl(self.fd.as_raw_fd(), libc::SIOCSIFFLAGS, &raw mut request) })?;
        Ok(())
    }
}

/// `CLOCK_MONOTONIC` in nanoseconds: the time base of a segment run in real time.
pub fn monotonic_ns() -> u64 {
    let mut spec = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: the timespec is valid for the call.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &raw mut spec) };
    (spec.tv_sec as u64)
        .saturating_mul(1_000_000_000)
        .saturating_add(spec.tv_nsec as u64)
}
