//! The MQTT publisher: retained machine state and program status, positions and overrides
//! at a set rate, alarms and operator messages as events that are kept until the broker
//! has acknowledged them (QoS 1, one at a time), however long it is away.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Duration;

use rtcnc_api::App;
use rtcnc_api::models::{Event, Status};
use rumqttc::{
    AsyncClient, ConnectionError, Event as MqttEvent, LastWill, MqttOptions, Packet, QoS,
    TlsConfiguration, Transport,
};
use serde_json::json;
use tokio::sync::{broadcast::error::RecvError, mpsc};

use crate::cnc;
use crate::config::{MqttSection, slug};

/// What the connection tells the publisher.
#[derive(Debug)]
enum Link {
    Connected { session_present: bool },
    Acked,
    Lost(String),
}

/// An alarm or message waiting for the broker's acknowledgement.
#[derive(Debug, Clone, PartialEq)]
pub struct Queued {
    /// Topic.
    pub topic: String,
    /// JSON.
    pub payload: String,
}

/// Alarms and messages in order, the first one in flight until acknowledged. When full,
/// the oldest not yet sent is dropped and counted (the one in flight stays).
#[derive(Debug, Default)]
pub struct EventQueue {
    items: VecDeque<Queued>,
    capacity: usize,
    in_flight: bool,
    dropped: u64,
}

impl EventQueue {
    /// Holding at most `capacity`.
    pub fn new(capacity: usize) -> EventQueue {
        EventQueue {
            capacity: capacity.max(1),
            ..EventQueue::default()
        }
    }

    /// Adds one at the end.
    pub fn push(&mut self, q: Queued) {
        if self.items.len() >= self.capacity {
            let oldest_unsent = usize::from(self.in_flight);
            if self.items.remove(oldest_unsent).is_some() {
                self.dropped += 1;
            }
        }
        self.items.push_back(q);
    }

    /// The next one to send, if none is in flight; it is then in flight.
    pub fn next_to_send(&mut self) -> Option<Queued> {
        if self.in_flight {
            return None;
        }
        let q = self.items.front().cloned()?;
        self.in_flight = true;
        Some(q)
    }

    /// The broker acknowledged the one in flight.
    pub fn acknowledged(&mut self) {
        if self.in_flight {
            self.items.pop_front();
            self.in_flight = false;
        }
    }

    /// The connection came back without the old session: the one in flight is sent again.
    pub fn resend(&mut self) {
        self.in_flight = false;
    }

    /// Waiting, in flight included.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Nothing waits.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

fn read_pem_certs(
    path: &std::path::Path,
) -> anyhow::Result<Vec<rustls::pki_types::CertificateDer<'static>>> {
    let data = std::fs::read(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let certs: Result<Vec<_>, _> = rustls_pemfile::certs(&mut data.as_slice()).collect();
    let certs = certs.map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    if certs.is_empty() {
        anyhow::bail!("{}: no PEM certificate", path.display());
    }
    Ok(certs)
}

fn tls_config(app: &App, section: &MqttSection) -> anyhow::Result<rustls::ClientConfig> {
    let mut roots = rustls::RootCertStore::empty();
    match &section.ca_certificate {
        Some(p) => {
            for c in read_pem_certs(&app.config.resolve(p))? {
                roots.add(c)?;
            }
        }
        None => {
            for c in rustls_native_certs::load_native_certs().certs {
                let _ = roots.add(c);
            }
        }
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()?
        .with_root_certificates(roots);
    Ok(match (&section.client_certificate, &section.client_key) {
        (Some(c), Some(k)) => {
            let certs = read_pem_certs(&app.config.resolve(c))?;
            let path = app.config.resolve(k);
            let data =
                std::fs::read(&path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            let key = rustls_pemfile::private_key(&mut data.as_slice())?
                .ok_or_else(|| anyhow::anyhow!("{}: no PEM private key", path.display()))?;
            builder.with_client_auth_cert(certs, key)?
        }
        _ => builder.with_no_client_auth(),
    })
}

/// The options of the broker connection.
fn options(app: &App, section: &MqttSection, prefix: &str) -> anyhow::Result<MqttOptions> {
    let port = section
        .port
        .unwrap_or(if section.tls { 8883 } else { 1883 });
    let client_id = section
        .client_id
        .clone()
        .unwrap_or_else(|| format!("rtcnc-{}", slug(&app.config.machine.name)));
    let mut o = MqttOptions::new(client_id, section.host.clone(), port);
    o.set_keep_alive(Duration::from_secs(section.keep_alive_s))
        // The broker keeps the session (and what it has not acknowledged) across a lost
        // connection; what it forgot is sent again from the publisher's own queue.
        .set_clean_session(false)
        .set_last_will(LastWill::new(
            format!("{prefix}/online"),
            "false",
            QoS::AtLeastOnce,
            true,
        ));
    if let Some(user) = &section.username {
        let password = match &section.password_file {
            Some(p) => {
                let path = app.config.resolve(p);
                std::fs::read_to_string(&path)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
                    .lines()
                    .next()
                    .unwrap_or("")
                    .to_string()
            }
            None => String::new(),
        };
        o.set_credentials(user.clone(), password);
    }
    if section.tls {
        o.set_transport(Transport::Tls(TlsConfiguration::Rustls(Arc::new(
            tls_config(app, section)?,
        ))));
    }
    Ok(o)
}

/// The topic prefix.
pub fn prefix(app: &App, section: &MqttSection) -> String {
    section
        .topic_prefix
        .clone()
        .unwrap_or_else(|| format!("rtcnc/{}", slug(&app.config.machine.name)))
}

/// `state`: retained.
pub fn state_payload(s: &Status) -> String {
    json!({
        "connected": s.connected,
        "state": s.state,
        "mode": s.mode,
        "ready": s.ready,
        "estop_input": s.estop_input,
        "hold": s.hold,
        "hold_message": s.hold_message,
        "fault_count": s.fault_count,
        "last_fault": s.last_fault,
    })
    .to_string()
}

/// `program`: retained.
pub fn program_payload(s: &Status) -> String {
    let status = match cnc::program_status(s) {
        cnc::ProgramStatus::Stopped => "stopped",
        cnc::ProgramStatus::Running => "running",
        cnc::ProgramStatus::Waiting => "waiting",
        cnc::ProgramStatus::Interrupted => "interrupted",
        cnc::ProgramStatus::Canceled => "canceled",
    };
    json!({
        "name": s.program,
        "status": status,
        "line": s.line,
        "ended": s.program_ended,
        "tool": s.tool,
    })
    .to_string()
}

/// `position`: at the rate.
pub fn position_payload(s: &Status) -> String {
    json!({
        "time_s": s.time_s,
        "cycle": s.cycle,
        "machine": s.machine_position,
        "work": s.work_position,
        "distance_to_go": s.distance_to_go,
        "path_speed": s.path_speed,
        "spindle_rpm": s.spindle.rpm,
    })
    .to_string()
}

/// `overrides`: at the rate.
pub fn overrides_payload(s: &Status) -> String {
    json!({
        "feed": s.overrides.feed,
        "rapid": s.overrides.rapid,
        "spindle": s.overrides.spindle,
    })
    .to_string()
}

/// `alarm` or `message` of an API event, if it is one.
pub fn event_message(prefix: &str, e: &Event, dropped_before: u64) -> Option<Queued> {
    let (topic, payload) = match e.kind.as_str() {
        "fault" => (
            "alarm",
            json!({
                "seq": e.seq,
                "code": e.code,
                "message": e.message,
                "time_s": e.time_s,
                "line": e.line,
                "joint": e.joint,
                "value": e.value,
                "dropped_before": dropped_before,
            }),
        ),
        "message" => (
            "message",
            json!({
                "seq": e.seq,
                "message": e.message,
                "time_s": e.time_s,
                "line": e.line,
            }),
        ),
        _ => return None,
    };
    Some(Queued {
        topic: format!("{prefix}/{topic}"),
        payload: payload.to_string(),
    })
}

/// Starts the publisher's tasks.
pub fn start(app: Arc<App>, section: MqttSection) -> anyhow::Result<()> {
    let prefix = prefix(&app, &section);
    let opts = options(&app, &section, &prefix)?;
    // The channel holds the rate's publishes between polls; events wait in the queue.
    let (client, mut eventloop) = AsyncClient::new(opts, 256);
    let (link_tx, link_rx) = mpsc::unbounded_channel();
    println!(
        "rtcnc api: MQTT to {}:{} under {prefix}/",
        section.host,
        section
            .port
            .unwrap_or(if section.tls { 8883 } else { 1883 })
    );
    tokio::spawn(async move {
        loop {
            let link = match eventloop.poll().await {
                Ok(MqttEvent::Incoming(Packet::ConnAck(c))) => Link::Connected {
                    session_present: c.session_present,
                },
                Ok(MqttEvent::Incoming(Packet::PubAck(_))) => Link::Acked,
                Ok(_) => continue,
                Err(e) => {
                    let reason = match &e {
                        ConnectionError::ConnectionRefused(c) => format!("refused: {c:?}"),
                        other => other.to_string(),
                    };
                    let _ = link_tx.send(Link::Lost(reason));
                    // Again in a second: the broker may be restarting.
                    tokio::time::sleep(Duration::from_secs(1)).await;
                    continue;
                }
            };
            if link_tx.send(link).is_err() {
                return;
            }
        }
    });
    tokio::spawn(publish(app, section, prefix, client, link_rx));
    Ok(())
}

async fn publish(
    app: Arc<App>,
    section: MqttSection,
    prefix: String,
    client: AsyncClient,
    mut link: mpsc::UnboundedReceiver<Link>,
) {
    let mut events = app.machine.subscribe_events();
    let mut status = app.machine.status_watch();
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / section.rate_hz));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut queue = EventQueue::new(section.queue);
    let mut connected = false;
    let mut last_state = String::new();
    let mut last_program = String::new();
    let mut lost_reported = false;
    let retained = |topic: &str, payload: String| {
        client.try_publish(format!("{prefix}/{topic}"), QoS::AtMostOnce, true, payload)
    };
    loop {
        tokio::select! {
            l = link.recv() => match l {
                Some(Link::Connected { session_present }) => {
                    connected = true;
                    lost_reported = false;
                    // What the broker forgot with the session is sent again.
                    if !session_present {
                        queue.resend();
                    }
                    let s = status.borrow().clone();
                    last_state = state_payload(&s);
                    last_program = program_payload(&s);
                    let _ = client.try_publish(format!("{prefix}/online"), QoS::AtLeastOnce, true, "true");
                    let _ = retained("state", last_state.clone());
                    let _ = retained("program", last_program.clone());
                }
                Some(Link::Acked) => queue.acknowledged(),
                Some(Link::Lost(reason)) => {
                    if !lost_reported {
                        eprintln!("rtcnc api: MQTT broker {}: {reason}; alarms are queued", section.host);
                        lost_reported = true;
                    }
                    connected = false;
                }
                None => return,
            },
            e = events.recv() => match e {
                Ok(e) => {
                    if let Some(q) = event_message(&prefix, &e, queue.dropped()) {
                        queue.push(q);
                    }
                }
                Err(RecvError::Lagged(n)) => {
                    eprintln!("rtcnc api: MQTT publisher missed {n} events (too slow)");
                }
                Err(RecvError::Closed) => return,
            },
            changed = status.changed() => {
                if changed.is_err() {
                    return;
                }
                let s = status.borrow_and_update().clone();
                if connected {
                    let state = state_payload(&s);
                    if state != last_state {
                        let _ = retained("state", state.clone());
                        last_state = state;
                    }
                    let program = program_payload(&s);
                    if program != last_program {
                        let _ = retained("program", program.clone());
                        last_program = program;
                    }
                }
            }
            _ = tick.tick() => {
                if connected {
                    let s = status.borrow().clone();
                    let _ = client.try_publish(format!("{prefix}/position"), QoS::AtMostOnce, false, position_payload(&s));
                    let _ = client.try_publish(format!("{prefix}/overrides"), QoS::AtMostOnce, false, overrides_payload(&s));
                }
            }
        }
        if connected {
            if let Some(q) = queue.next_to_send() {
                if client
                    .try_publish(q.topic, QoS::AtLeastOnce, false, q.payload)
                    .is_err()
                {
                    // The channel is full of rate publishes: next turn.
                    queue.resend();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(n: u32) -> Queued {
        Queued {
            topic: "t".into(),
            payload: n.to_string(),
        }
    }

    #[test]
    fn one_in_flight_until_acknowledged() {
        let mut e = EventQueue::new(10);
        e.push(q(1));
        e.push(q(2));
        assert_eq!(e.next_to_send(), Some(q(1)));
        assert_eq!(e.next_to_send(), None, "stop and wait");
        e.acknowledged();
        assert_eq!(e.next_to_send(), Some(q(2)));
        e.acknowledged();
        assert!(e.is_empty());
        e.acknowledged();
        assert!(
            e.is_empty(),
            "an ack with nothing in flight changes nothing"
        );
    }

    #[test]
    fn a_lost_session_sends_the_one_in_flight_again() {
        let mut e = EventQueue::new(10);
        e.push(q(1));
        assert_eq!(e.next_to_send(), Some(q(1)));
        e.resend();
        assert_eq!(e.next_to_send(), Some(q(1)));
        assert_eq!(e.len(), 1);
    }

    #[test]
    fn full_drops_the_oldest_unsent_and_counts() {
        let mut e = EventQueue::new(3);
        for n in 1..=3 {
            e.push(q(n));
        }
        assert_eq!(e.next_to_send(), Some(q(1)));
        e.push(q(4));
        assert_eq!(e.dropped(), 1);
        e.acknowledged();
        // 2 was the oldest not in flight.
        assert_eq!(e.next_to_send(), Some(q(3)));
        e.acknowledged();
        assert_eq!(e.next_to_send(), Some(q(4)));
    }
}
