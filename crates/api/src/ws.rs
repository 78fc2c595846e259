//! The WebSocket (`GET /api/ws`): a snapshot first, then the status changes at the rate the
//! client picks (merge patches of the last status sent), events, trace samples and a
//! heartbeat. docs/api.md describes the protocol.

use std::sync::Arc;
use std::time::Duration;

use axum::extract::State;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::response::Response;
use futures_util::{SinkExt, StreamExt};
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::sync::broadcast::error::RecvError;

use crate::App;
use crate::auth::Role;
use crate::problem::ApiResult;
use crate::routes::Caller;

/// What a client may send.
#[derive(Debug, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
enum ClientMessage {
    /// Choose what to receive.
    Subscribe {
        /// Status messages per second, 1..100 (default 10).
        #[serde(default)]
        rate_hz: Option<f64>,
        /// Events (default true).
        #[serde(default)]
        events: Option<bool>,
        /// Trace samples (default false), every `trace_decimation`-th period.
        #[serde(default)]
        trace: Option<bool>,
        #[serde(default)]
        trace_decimation: Option<u32>,
    },
    /// Keep a continuous jog going (needs the lease).
    JogKeepAlive { axis: String },
    /// Answered with a pong.
    Ping {
        #[serde(default)]
        id: Option<u64>,
    },
}

/// The WebSocket: a snapshot, then changes, events, trace samples and a heartbeat (see
/// docs/api.md). The token may come as `?token=`.
#[utoipa::path(get, path = "/api/ws", tag = "status", security(("bearer" = [])),
    params(("token" = Option<String>, Query, description = "The session token, for clients that cannot set headers")),
    responses((status = 101, description = "Switching to the WebSocket protocol"),
        (status = 401, body = crate::problem::Problem, content_type = "application/problem+json")))]
pub async fn ws(
    State(app): State<Arc<App>>,
    caller: Caller,
    upgrade: WebSocketUpgrade,
) -> ApiResult<Response> {
    caller.session.require(Role::Viewer)?;
    Ok(upgrade
        .max_message_size(crate::MAX_WS_MESSAGE)
        .max_frame_size(crate::MAX_WS_MESSAGE)
        .on_upgrade(move |socket| session(app, caller, socket)))
}

fn diff(old: &Value, new: &Value) -> Option<Value> {
    let (Value::Object(o), Value::Object(n)) = (old, new) else {
        return Some(new.clone());
    };
    let mut patch = serde_json::Map::new();
    for (k, v) in n {
        if o.get(k) != Some(v) {
            patch.insert(k.clone(), v.clone());
        }
    }
    (!patch.is_empty()).then_some(Value::Object(patch))
}

async fn session(app: Arc<App>, caller: Caller, socket: WebSocket) {
    let (mut tx, mut rx) = socket.split();
    let mut events = app.machine.subscribe_events();
    let mut trace = app.machine.subscribe_trace();
    let mut rate = 10.0f64;
    let mut want_events = true;
    let mut want_trace = false;
    let mut decimation = 10u32;
    let mut trace_count = 0u64;
    let status = serde_json::to_value(app.status_now()).unwrap_or(Value::Null);
    let hello = json!({
        "type": "snapshot",
        "status": status,
        "last_seq": app.machine.last_seq(),
        "user": caller.session.user,
        "role": caller.session.role.as_str(),
    });
    if tx
        .send(Message::Text(hello.to_string().into()))
        .await
        .is_err()
    {
        return;
    }
    let mut last = status;
    // A client slower than its rate gets fewer, newer patches, not a burst of stale ones.
    let skip = tokio::time::MissedTickBehavior::Skip;
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / rate));
    tick.set_missed_tick_behavior(skip);
    let mut beat = tokio::time::interval(Duration::from_secs(1));
    beat.set_missed_tick_behavior(skip);
    loop {
        let out: Option<Value> = tokio::select! {
            _ = tick.tick() => {
                let now = serde_json::to_value(app.status_now()).unwrap_or(Value::Null);
                let patch = diff(&last, &now);
                last = now;
                patch.map(|p| json!({"type": "status", "changes": p}))
            }
            _ = beat.tick() => {
                // Sessions expire on the WebSocket too.
                if app.auth.session(Some(&caller.token)).is_err() {
                    let _ = tx.send(Message::Text(json!({"type": "closing", "reason": "session expired"}).to_string().into())).await;
                    break;
                }
                Some(json!({"type": "heartbeat", "machine_connected": app.machine.connected(), "last_seq": app.machine.last_seq()}))
            }
            e = events.recv() => match e {
                Ok(e) if want_events => Some(json!({"type": "event", "event": *e})),
                Ok(_) => None,
                Err(RecvError::Lagged(n)) => Some(json!({"type": "events_lost", "count": n, "hint": "GET /api/events?since=<last seq> has them"})),
                Err(RecvError::Closed) => break,
            },
            t = trace.recv(), if want_trace => match t {
                Ok(batch) => {
                    let mut samples = Vec::new();
                    for s in batch.iter() {
                        trace_count += 1;
                        if trace_count % u64::from(decimation) == 0 {
                            samples.push(json!({
                                "cycle": s.cycle,
                                "time_s": s.time_ns as f64 * 1e-9,
                                "line": s.line,
                                "path_speed": s.path_speed,
                                "setpoint": &s.setpoint[..s.joints as usize],
                                "feedback": &s.feedback[..s.joints as usize],
                                "following_error": &s.following_error[..s.joints as usize],
                            }));
                        }
                    }
                    (!samples.is_empty()).then(|| json!({"type": "trace", "samples": samples}))
                }
                Err(RecvError::Lagged(n)) => Some(json!({"type": "trace_lost", "batches": n})),
                Err(RecvError::Closed) => break,
            },
            m = rx.next() => match m {
                Some(Ok(Message::Text(text))) => match serde_json::from_str::<ClientMessage>(&text) {
                    Ok(ClientMessage::Subscribe { rate_hz, events, trace, trace_decimation }) => {
                        rate = rate_hz.unwrap_or(rate).clamp(1.0, 100.0);
                        tick = tokio::time::interval(Duration::from_secs_f64(1.0 / rate));
                        tick.set_missed_tick_behavior(skip);
                        want_events = events.unwrap_or(want_events);
                        want_trace = trace.unwrap_or(want_trace);
                        decimation = trace_decimation.unwrap_or(decimation).max(1);
                        Some(json!({"type": "subscribed", "rate_hz": rate, "events": want_events, "trace": want_trace, "trace_decimation": decimation}))
                    }
                    Ok(ClientMessage::JogKeepAlive { axis }) => {
                        match crate::ws_keep_alive(&app, &caller, &axis) {
                            Ok(()) => None,
                            Err(p) => Some(json!({"type": "error", "problem": p})),
                        }
                    }
                    Ok(ClientMessage::Ping { id }) => Some(json!({"type": "pong", "id": id})),
                    Err(e) => Some(json!({"type": "error", "problem": crate::problem::Problem::bad_request("ws.bad_message", e.to_string())})),
                },
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                Some(Ok(_)) => None,
            },
        };
        if let Some(v) = out {
            if tx.send(Message::Text(v.to_string().into())).await.is_err() {
                break;
            }
        }
    }
}
