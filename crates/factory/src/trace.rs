//! The fast values from the machine's trace: every servo period's sample (set-points,
//! feedback, path speed), which the machine process writes to its trace ring in shared
//! memory and the API process drains in batches (`MachineConn::subscribe_trace`). Monitored
//! items that sample faster than the API's status documents take the values the trace
//! carries from its samples, each with the sample's own machine time, so none is missed
//! however late this process gets the processor: the ring holds them until it does.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use opcua::server::MonitoredItemHandle;
use opcua::server::SubscriptionCache;
use opcua::types::{AttributeId, DataValue, DateTime, NodeId, StatusCode, Variant};
use rtcnc_kernel::link::layout::TraceSample;
use tokio::sync::broadcast;
use tokio::sync::broadcast::error::RecvError;

use crate::sampling::{Clock, Decimator, MachineNodeManager};

/// What a node's value is, from one trace sample.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// The axis set-point (machine coordinates), by axis index (X = 0 … W = 8).
    Command(usize),
    /// The mean feedback of the axis's joints (by joint index); the set-point of the axis
    /// (by axis index) when it has none.
    Actual(usize, Vec<usize>),
    /// The path speed in units per minute.
    Feedrate,
}

impl Source {
    /// The value in `s`, as the status document's value of the same node is computed.
    pub fn value(&self, s: &TraceSample) -> f64 {
        match self {
            Source::Command(axis) => s.axes.get(*axis).copied().unwrap_or(0.0),
            Source::Actual(axis, joints) => {
                // Summed in joint order, as the status document's mean is: the same value.
                let (sum, n) = joints
                    .iter()
                    .filter_map(|&j| s.feedback.get(j))
                    .fold((0.0, 0usize), |(sum, n), v| (sum + v, n + 1));
                if n == 0 {
                    Source::Command(*axis).value(s)
                } else {
                    sum / n as f64
                }
            }
            Source::Feedrate => s.path_speed * 60.0,
        }
    }
}

/// The nodes whose values the trace carries.
pub type TraceNodes = Arc<Vec<(NodeId, Source)>>;

/// How often the samples the monitored items missed are reported.
const REPORT_EVERY: Duration = Duration::from_secs(1);

/// The trace's samples to the monitored items of the nodes it carries.
pub struct TraceFeed {
    nodes: TraceNodes,
    rx: broadcast::Receiver<Arc<Vec<TraceSample>>>,
    clock: Clock,
    /// The machine's time of the last sample received, ns.
    last_time: Option<u64>,
    /// Samples up to this cycle are older than the values already set.
    after: Option<u64>,
    /// Every monitored item's step (servo periods between its samples).
    items: HashMap<MonitoredItemHandle, Decimator>,
    /// Batches of samples this reader lost (it fell behind the API's broadcast), and
    /// samples the machine dropped from its full trace ring, since the last report.
    lagged: u64,
    dropped: u64,
    /// The machine's count of dropped samples when last seen.
    dropped_seen: Option<u64>,
    reported: Instant,
}

impl TraceFeed {
    /// From the samples after `after` on, with source timestamps from the wall-clock time
    /// `zero` (ticks) of the machine's time zero when known; samples `period` ticks apart.
    pub fn new(
        rx: broadcast::Receiver<Arc<Vec<TraceSample>>>,
        nodes: TraceNodes,
        period: i64,
        zero: Option<i64>,
        after: Option<u64>,
    ) -> Self {
        TraceFeed {
            nodes,
            rx,
            clock: Clock::seeded(period, zero),
            last_time: None,
            after,
            items: HashMap::new(),
            lagged: 0,
            dropped: 0,
            dropped_seen: None,
            reported: Instant::now(),
        }
    }

    /// The monitored items of the trace's nodes, each with its step.
    pub fn set_steps(&mut self, steps: &HashMap<MonitoredItemHandle, u64>) {
        self.items.retain(|h, _| steps.contains_key(h));
        for (h, step) in steps {
            self.items
                .entry(*h)
                .or_insert_with(|| Decimator::new(*step))
                .set_step(*step);
        }
    }

    /// The next batch of samples; `None` when the machine's side is gone for good.
    pub async fn recv(&mut self) -> Option<Arc<Vec<TraceSample>>> {
        loop {
            match self.rx.recv().await {
                Ok(batch) => return Some(batch),
                Err(RecvError::Lagged(n)) => self.lagged += n,
                Err(RecvError::Closed) => return None,
            }
        }
    }

    /// Hands a batch's samples to the monitored items, each item those of its step, with
    /// their source timestamps; the newest sample's values become the nodes' values.
    /// `ring_dropped` is the machine's count of samples its full trace ring dropped.
    ///
    /// A sample's cycle is that of its set-point: the same in the periods a stalled
    /// interpolation leaves the servo without a new one, and then ahead by as many. An
    /// item takes one sample per cycle on its grid, so such periods give it none.
    pub fn feed(
        &mut self,
        batch: &[TraceSample],
        manager: &MachineNodeManager,
        subscriptions: &SubscriptionCache,
        ring_dropped: u64,
    ) {
        let now = DateTime::now();
        let mut newest: Option<(Vec<f64>, DateTime)> = None;
        {
            let mut notifier = subscriptions.data_notifier();
            for s in batch {
                // A restarted machine's time starts from zero again.
                if self.last_time.is_some_and(|t| s.time_ns < t) {
                    self.clock.reset();
                    self.after = None;
                    for d in self.items.values_mut() {
                        *d = Decimator::new(d.step());
                    }
                }
                self.last_time = Some(s.time_ns);
                if self.after.is_some_and(|a| s.cycle <= a) {
                    continue;
                }
                let source =
                    DateTime::from(self.clock.stamp((s.time_ns / 100) as i64, now.ticks()));
                let values: Vec<f64> = self.nodes.iter().map(|(_, src)| src.value(s)).collect();
                for ((id, _), v) in self.nodes.iter().zip(&values) {
                    let Some(mut items) = notifier.notify_for(id, AttributeId::Value) else {
                        continue;
                    };
                    let handles: Vec<MonitoredItemHandle> =
                        items.entries().map(|(h, _)| *h).collect();
                    for h in handles {
                        // An item not yet known takes its samples once its step is.
                        if self.items.get_mut(&h).is_some_and(|d| d.take(s.cycle)) {
                            items.data_value_to_item(data_value(*v, source, now), &h);
                        }
                    }
                }
                newest = Some((values, source));
            }
            // The notifications go to the subscriptions here, as the notifier is dropped.
        }
        if let Some((values, source)) = newest {
            let mut space = manager.address_space().write();
            for ((id, _), v) in self.nodes.iter().zip(values) {
                if let Some(opcua::nodes::NodeType::Variable(var)) = space.find_mut(id) {
                    var.set_data_value(data_value(v, source, now));
                }
            }
        }
        self.report(ring_dropped);
    }

    /// Says when samples were lost on the way (the machine's trace ring overflowed, or this
    /// reader fell further behind than the API's broadcast holds), at most once a second.
    fn report(&mut self, ring_dropped: u64) {
        if let Some(seen) = self.dropped_seen {
            self.dropped += ring_dropped.saturating_sub(seen);
        }
        self.dropped_seen = Some(ring_dropped);
        if (self.dropped == 0 && self.lagged == 0) || self.reported.elapsed() < REPORT_EVERY {
            return;
        }
        eprintln!(
            "rtcnc api: OPC UA: in the last {:.1} s the machine's full trace ring dropped {} \
             samples and the OPC UA server fell behind by {} batches of them: the monitored \
             items sampling faster than 10 ms lack those",
            self.reported.elapsed().as_secs_f64(),
            self.dropped,
            self.lagged,
        );
        self.dropped = 0;
        self.lagged = 0;
        self.reported = Instant::now();
    }
}

fn data_value(v: f64, source: DateTime, now: DateTime) -> DataValue {
    DataValue {
        value: Some(Variant::from(v)),
        status: Some(StatusCode::Good),
        source_timestamp: Some(source),
        server_timestamp: Some(now),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(cycle: u64) -> TraceSample {
        let mut s = TraceSample {
            cycle,
            time_ns: cycle * 1_000_000,
            line: 0,
            joints: 3,
            path_speed: 20.0,
            axes: [0.0; rtcnc_kernel::link::layout::AXES],
            setpoint: [0.0; rtcnc_kernel::config::MAX_JOINTS],
            feedback: [0.0; rtcnc_kernel::config::MAX_JOINTS],
            following_error: [0.0; rtcnc_kernel::config::MAX_JOINTS],
        };
        s.axes[0] = 1.5;
        s.axes[1] = 2.0;
        s.feedback[0] = 1.25;
        s.feedback[1] = 1.75;
        s.feedback[2] = 4.0;
        s
    }

    /// The values as the status document's: the set-point, the mean feedback of the
    /// axis's joints (the set-point without joints), the path speed per minute.
    #[test]
    fn values_from_a_sample() {
        let s = sample(7);
        assert_eq!(Source::Command(0).value(&s), 1.5);
        assert_eq!(Source::Actual(0, vec![0, 1]).value(&s), 1.5);
        assert_eq!(Source::Actual(2, vec![2]).value(&s), 4.0);
        assert_eq!(Source::Actual(1, vec![]).value(&s), 2.0);
        assert_eq!(Source::Feedrate.value(&s), 1200.0);
    }
}
