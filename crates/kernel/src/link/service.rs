//! The machine process's service thread (not real time): PLC variables for the client
//! (read, force, unforce, the watch list and its values) and the executive's task timing.
//! It takes the PLC runtime's PI mutex only for a look-up or a copy of a few values.

use std::sync::Arc;

use rtcnc_plc::{Runtime, Value, VarRef};
use rtcnc_rt::{PiMutex, TaskStats};

use super::layout::{self, ServiceReply, ServiceRequest, WireText, WireTiming, service};
use super::machine::MachineLink;
use super::segment::Mapping;

/// Serves the client's requests; call [`poll`](Self::poll) every few milliseconds.
pub struct ServiceThread {
    map: Mapping,
    plc: Option<Arc<PiMutex<Runtime>>>,
    watch: Vec<VarRef>,
    list: u64,
}

fn number(v: &Value) -> f64 {
    match v {
        Value::Bool(b) => f64::from(u8::from(*b)),
        Value::Int(i) | Value::Time(i) => *i as f64,
        Value::UInt(u) => *u as f64,
        Value::Real(r) => *r,
        Value::String(_) => f64::NAN,
    }
}

impl ServiceThread {
    /// For the machine's link and its PLC (none on a machine with the direct logic).
    pub fn new(link: &MachineLink, plc: Option<Arc<PiMutex<Runtime>>>) -> ServiceThread {
        ServiceThread {
            map: link.mapping().clone(),
            plc,
            watch: Vec::new(),
            list: 0,
        }
    }

    /// Answers every waiting request and publishes the watched values.
    pub fn poll(&mut self) {
        let map = self.map.clone();
        let seg = map.segment();
        // SAFETY: the service thread is the request ring's only consumer.
        while let Some(r) = unsafe { seg.requests.pop() } {
            let reply = self.handle(&r);
            // SAFETY: and the reply ring's only producer. A client that does not read its
            // replies loses the newest.
            let _ = unsafe { seg.replies.push(reply) };
        }
        if let Some(plc) = &self.plc {
            let mut w = layout::WireWatch {
                list: self.list,
                count: self.watch.len().min(layout::WATCH_SLOTS) as u32,
                ..Default::default()
            };
            {
                let rt = plc.lock();
                let forced: Vec<u32> = rt.forced_slots().collect();
                for (i, var) in self.watch.iter().take(layout::WATCH_SLOTS).enumerate() {
                    w.values[i] = number(&rt.read(var));
                    if forced.contains(&var.slot()) {
                        w.forced |= 1 << i;
                    }
                }
            }
            // SAFETY: the service thread is the watch cell's only writer.
            unsafe { seg.watch.publish(w) };
        }
    }

    fn handle(&mut self, r: &ServiceRequest) -> ServiceReply {
        let mut reply = ServiceReply {
            serial: r.serial,
            ..Default::default()
        };
        let refuse = |reply: &mut ServiceReply, code: &str, text: &str| {
            reply.ok = 0;
            reply.code = WireText::new(code);
            reply.text = WireText::new(text);
        };
        let Some(plc) = &self.plc else {
            refuse(
                &mut reply,
                "plc.absent",
                "this machine runs the kernel's direct logic, not a PLC program",
            );
            return reply;
        };
        let path = r.text.as_str().trim();
        let mut rt = plc.lock();
        let resolved = |rt: &Runtime, path: &str| rt.resolve(path);
        match r.kind {
            service::PLC_READ => match rt.read_name(path) {
                Ok(v) => {
                    reply.ok = 1;
                    reply.text = WireText::new(&v.to_string());
                }
                Err(e) => refuse(&mut reply, &format!("plc.{}", e.code()), &e.to_string()),
            },
            service::PLC_FORCE => match resolved(&rt, path) {
                Ok(var) => match rt.parse_value(&var, r.value_text.as_str().trim()) {
                    Ok(value) => match rt.force(&var, &value) {
                        Ok(()) => {
                            reply.ok = 1;
                            reply.text = WireText::new(&value.to_string());
                        }
                        Err(e) => refuse(&mut reply, &format!("plc.{}", e.code()), &e.to_string()),
                    },
                    Err(e) => refuse(&mut reply, "plc.bad-value", &e.to_string()),
                },
                Err(e) => refuse(&mut reply, &format!("plc.{}", e.code()), &e.to_string()),
            },
            service::PLC_UNFORCE => match resolved(&rt, path) {
                Ok(var) => {
                    rt.unforce(&var);
                    reply.ok = 1;
                }
                Err(e) => refuse(&mut reply, &format!("plc.{}", e.code()), &e.to_string()),
            },
            service::PLC_WATCH => {
                let mut list = Vec::new();
                for p in path.split(',').map(str::trim).filter(|p| !p.is_empty()) {
                    match resolved(&rt, p) {
                        Ok(var) if var.elem().is_some() => list.push(var),
                        Ok(_) => {
                            refuse(
                                &mut reply,
                                "plc.not-scalar",
                                &format!("'{p}' is not an elementary number or BOOL"),
                            );
                            return reply;
                        }
                        Err(e) => {
                            refuse(&mut reply, &format!("plc.{}", e.code()), &e.to_string());
                            return reply;
                        }
                    }
                }
                if list.len() > layout::WATCH_SLOTS {
                    refuse(
                        &mut reply,
                        "plc.watch-full",
                        &format!("at most {} variables", layout::WATCH_SLOTS),
                    );
                    return reply;
                }
                drop(rt);
                self.watch = list;
                self.list += 1;
                reply.ok = 1;
                reply.text = WireText::new(&self.list.to_string());
            }
            _ => refuse(&mut reply, "plc.unknown-request", "unknown request"),
        }
        reply
    }

    /// Publishes the executive's task timing and the set-point underruns.
    pub fn publish_timing(&self, stats: &[TaskStats], fifo: bool, underruns: u64) {
        let mut t = WireTiming {
            count: stats.len().min(layout::TIMING_SLOTS) as u32,
            fifo: u32::from(fifo),
            underruns,
            ..Default::default()
        };
        for (slot, s) in t.tasks.iter_mut().zip(stats) {
            slot.name = layout::name_field(&s.name);
            slot.activations = s.activations;
            slot.execution_mean_ns = s.execution.mean;
            slot.execution_p99_ns = s.execution.p99;
            slot.execution_max_ns = s.execution.max;
            slot.lateness_p99_ns = s.lateness.p99;
            slot.lateness_max_ns = s.lateness.max;
            slot.deadline_misses = s.deadline_misses;
            slot.skipped_releases = s.skipped_releases;
        }
        // SAFETY: the service thread is the timing cell's only writer.
        unsafe { self.map.segment().timing.publish(t) };
    }
}
