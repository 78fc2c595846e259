//! The node manager of the machine's instance nodes: an in-memory address space that also
//! keeps the node and sampling interval of every monitored item on those nodes, so the
//! values are read from the machine as often as the fastest of them asks, and no faster;
//! and the arithmetic of sampling: which servo-period samples an item takes, and the
//! source timestamps.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use opcua::server::CreateMonitoredItem;
use opcua::server::MonitoredItemHandle;
use opcua::server::address_space::AddressSpace;
use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::{
    InMemoryNodeManager, InMemoryNodeManagerBuilder, InMemoryNodeManagerImpl,
};
use opcua::server::node_manager::{
    MonitoredItemRef, MonitoredItemUpdateRef, NodeManagerBuilder, RequestContext, ServerContext,
};
use opcua::sync::RwLock;
use opcua::types::{MonitoringMode, NodeId, StatusCode, TimestampsToReturn};
use tokio::sync::watch;

/// The machine's node manager.
pub type MachineNodeManager = InMemoryNodeManager<MachineNodes>;

/// No monitored item samples (or none asks for an interval of its own).
pub const NOBODY_SAMPLES: f64 = f64::INFINITY;

/// The sampling (not disabled) monitored items of the machine's nodes: each one's node
/// and sampling interval (ms; negative: the subscription's).
pub type Sampling = Arc<HashMap<MonitoredItemHandle, (NodeId, f64)>>;

type Items = HashMap<MonitoredItemHandle, (NodeId, f64)>;

/// The in-memory nodes of the machine and the sampling intervals asked of them.
pub struct MachineNodes {
    name: String,
    namespaces: Vec<NamespaceMetadata>,
    /// Node and sampling interval (ms) of each sampling monitored item.
    intervals: Mutex<Items>,
    /// Monitored items that exist, sampling or not, with their node and interval.
    known: Mutex<Items>,
    sampling: watch::Sender<Sampling>,
}

impl MachineNodes {
    /// Publishes the sampling items, when they changed.
    fn update(&self, intervals: &Items) {
        self.sampling.send_if_modified(|s| {
            let changed = **s != *intervals;
            if changed {
                *s = Arc::new(intervals.clone());
            }
            changed
        });
    }

    fn lock(m: &Mutex<Items>) -> std::sync::MutexGuard<'_, Items> {
        m.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The fastest of the sampling intervals (ms), [`NOBODY_SAMPLES`] without any. A negative
/// interval means "the subscription's publishing interval", which the node manager is not
/// told: such items are served at the API's status rate.
pub fn fastest_interval(intervals: impl Iterator<Item = f64>) -> f64 {
    intervals
        .filter(|i| *i > 0.0)
        .fold(NOBODY_SAMPLES, f64::min)
}

/// A builder of the machine's node manager in `namespace_uri`; `sampling` receives its
/// sampling monitored items whenever they change.
pub fn machine_node_manager(
    namespace_uri: String,
    name: &str,
    sampling: watch::Sender<Sampling>,
) -> impl NodeManagerBuilder {
    let name = name.to_string();
    InMemoryNodeManagerBuilder::new(
        move |context: ServerContext, space: &mut AddressSpace| -> MachineNodes {
            let index = context
                .type_tree
                .write()
                .namespaces_mut()
                .add_namespace(&namespace_uri);
            space.add_namespace(&namespace_uri, index);
            MachineNodes {
                name,
                namespaces: vec![NamespaceMetadata {
                    namespace_uri,
                    namespace_index: index,
                    ..Default::default()
                }],
                intervals: Mutex::new(HashMap::new()),
                known: Mutex::new(HashMap::new()),
                sampling,
            }
        },
    )
}

#[async_trait::async_trait]
impl InMemoryNodeManagerImpl for MachineNodes {
    async fn init(&self, _space: &mut AddressSpace, _context: ServerContext) {}

    fn name(&self) -> &str {
        &self.name
    }

    fn namespaces(&self) -> Vec<NamespaceMetadata> {
        self.namespaces.clone()
    }

    async fn create_value_monitored_items(
        &self,
        context: &RequestContext,
        space: &RwLock<AddressSpace>,
        items: &mut [&mut &mut CreateMonitoredItem],
    ) {
        // The initial values, as the in-memory manager reads them.
        let to_read: Vec<_> = items.iter().map(|r| r.item_to_monitor()).collect();
        let values = self
            .read_values(context, space, &to_read, 0.0, TimestampsToReturn::Both)
            .await;
        let mut known = Self::lock(&self.known);
        let mut intervals = Self::lock(&self.intervals);
        for (value, item) in values.into_iter().zip(items.iter_mut()) {
            if value.status() != StatusCode::BadAttributeIdInvalid {
                item.set_initial_value(value);
            }
            item.set_status(StatusCode::Good);
            let entry = (
                item.item_to_monitor().node_id.clone(),
                item.sampling_interval(),
            );
            if item.monitoring_mode() != MonitoringMode::Disabled {
                intervals.insert(item.handle(), entry.clone());
            }
            known.insert(item.handle(), entry);
        }
        self.update(&intervals);
    }

    async fn modify_monitored_items(
        &self,
        _context: &RequestContext,
        items: &[&MonitoredItemUpdateRef],
    ) {
        let mut known = Self::lock(&self.known);
        let mut intervals = Self::lock(&self.intervals);
        for it in items {
            let interval = it.update().revised_sampling_interval;
            known.insert(it.handle(), (it.node_id().clone(), interval));
            if let Some(i) = intervals.get_mut(&it.handle()) {
                i.1 = interval;
            }
        }
        self.update(&intervals);
    }

    async fn set_monitoring_mode(
        &self,
        _context: &RequestContext,
        mode: MonitoringMode,
        items: &[&MonitoredItemRef],
    ) {
        let known = Self::lock(&self.known);
        let mut intervals = Self::lock(&self.intervals);
        for it in items {
            match (mode, known.get(&it.handle())) {
                (MonitoringMode::Disabled, _) => {
                    intervals.remove(&it.handle());
                }
                (_, Some(i)) => {
                    intervals.insert(it.handle(), i.clone());
                }
                (_, None) => {}
            }
        }
        self.update(&intervals);
    }

    async fn delete_monitored_items(&self, _context: &RequestContext, items: &[&MonitoredItemRef]) {
        let mut known = Self::lock(&self.known);
        let mut intervals = Self::lock(&self.intervals);
        for it in items {
            known.remove(&it.handle());
            intervals.remove(&it.handle());
        }
        self.update(&intervals);
    }
}

/// The samples an item with a sampling interval of `interval_ms` takes, every how many
/// servo periods: the interval rounded up to whole periods (at least one), so that no two
/// values are closer than the interval and each keeps its own sample's time. A negative
/// interval (the subscription's) counts as 10 ms, as for the status documents.
pub fn step_of(interval_ms: f64, period_ms: f64) -> u64 {
    let interval = if interval_ms > 0.0 { interval_ms } else { 10.0 };
    if period_ms.is_nan() || period_ms <= 0.0 || !interval.is_finite() {
        return 1;
    }
    // A hair under a whole number of periods is that number (1.0 / 0.1 is 10.000000000000002).
    ((interval / period_ms) - 1e-9).ceil().max(1.0) as u64
}

/// Which servo-period samples (by cycle) one monitored item takes: the first at or after a
/// multiple of its step, then every `step` cycles; after a gap (samples lost) the first one
/// there is, and on from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decimator {
    step: u64,
    next: Option<u64>,
}

impl Decimator {
    /// Every `step` cycles.
    pub fn new(step: u64) -> Self {
        Decimator {
            step: step.max(1),
            next: None,
        }
    }

    /// Its step.
    pub fn step(&self) -> u64 {
        self.step
    }

    /// Another step, from the next sample on the new grid.
    pub fn set_step(&mut self, step: u64) {
        let step = step.max(1);
        if step != self.step {
            *self = Decimator::new(step);
        }
    }

    /// Whether the sample of `cycle` is taken.
    pub fn take(&mut self, cycle: u64) -> bool {
        let next = *self
            .next
            .get_or_insert(cycle.div_ceil(self.step) * self.step);
        if cycle < next {
            return false;
        }
        self.next = Some(cycle + self.step);
        true
    }
}

/// The source timestamps of the machine's samples: the machine's time (ticks of 100 ns
/// since its start) put on the wall clock (ticks since the OPC UA epoch), in whole ticks,
/// so that samples a period apart are exactly that apart and a monitored item sampling at
/// that period takes each one. The machine's time zero on the wall clock is the earliest
/// seen (a reading's own delay is not part of it), moved back only within the time a
/// skipped sample leaves (at most 50 µs a reading), so source timestamps never go
/// backwards nor come closer than a period; it is taken afresh when a second off (a step
/// of the wall clock, a restarted machine).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Clock {
    /// The wall-clock time of the machine's time zero.
    zero: Option<i64>,
    /// The machine's time of the last sample.
    last: Option<i64>,
    /// The period of the samples, ticks.
    period: i64,
}

impl Clock {
    /// For samples `period` ticks apart.
    pub fn new(period: i64) -> Self {
        Clock {
            zero: None,
            last: None,
            period,
        }
    }

    /// Starting from another clock's zero (the same machine's time, another feed).
    pub fn seeded(period: i64, zero: Option<i64>) -> Self {
        Clock {
            zero,
            last: None,
            period,
        }
    }

    /// The wall-clock time of the machine's time zero, when known.
    pub fn zero(&self) -> Option<i64> {
        self.zero
    }

    /// Forgets the machine's time zero.
    pub fn reset(&mut self) {
        *self = Clock::new(self.period);
    }

    /// The source timestamp (ticks) of a sample of machine time `machine`, read at `now`.
    pub fn stamp(&mut self, machine: i64, now: i64) -> i64 {
        let zero = now - machine;
        let since = self.last.map_or(0, |last| machine - last);
        self.last = Some(machine);
        let zero = match self.zero {
            Some(c) if (zero - c).abs() < 10_000_000 => {
                let room = (since - self.period).clamp(0, 500);
                c.min(zero.max(c - room))
            }
            _ => zero,
        };
        self.zero = Some(zero);
        zero + machine
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fastest_interval_ignores_the_subscription_default() {
        assert_eq!(fastest_interval([].into_iter()), NOBODY_SAMPLES);
        assert_eq!(fastest_interval([-1.0].into_iter()), NOBODY_SAMPLES);
        assert_eq!(fastest_interval([100.0, 1.0, -1.0, 10.0].into_iter()), 1.0);
    }

    #[test]
    fn steps_round_up_to_whole_periods() {
        assert_eq!(step_of(1.0, 1.0), 1);
        assert_eq!(step_of(0.5, 1.0), 1);
        assert_eq!(step_of(2.5, 1.0), 3);
        assert_eq!(step_of(100.0, 1.0), 100);
        assert_eq!(step_of(1.0, 0.1), 10);
        assert_eq!(
            step_of(-1.0, 1.0),
            10,
            "the subscription's interval counts as 10 ms"
        );
        assert_eq!(step_of(f64::INFINITY, 1.0), 1);
    }

    /// A 1 ms and a 100 ms item over the same batches of samples: the first takes every
    /// one, the second every hundredth, on multiples of 100, however the batches fall.
    #[test]
    fn each_item_takes_one_sample_per_its_interval() {
        let mut fast = Decimator::new(step_of(1.0, 1.0));
        let mut slow = Decimator::new(step_of(100.0, 1.0));
        let (mut f, mut s) = (Vec::new(), Vec::new());
        // Batches of 1, 7, 250, 3 and the rest, cycles 1017..2017.
        let mut cycle = 1017u64;
        for len in [1usize, 7, 250, 3, 739] {
            for _ in 0..len {
                if fast.take(cycle) {
                    f.push(cycle);
                }
                if slow.take(cycle) {
                    s.push(cycle);
                }
                cycle += 1;
            }
        }
        assert_eq!(cycle, 2017);
        assert_eq!(f, (1017..2017).collect::<Vec<_>>());
        assert_eq!(
            s,
            vec![1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900, 2000]
        );
    }

    /// Lost samples: the next one there is, and a full step on from it.
    #[test]
    fn after_a_gap_the_next_sample_there_is() {
        let mut d = Decimator::new(5);
        let taken: Vec<u64> = [0u64, 1, 2, 3, 4, 5, 6, 12, 13, 14, 15, 16, 17, 18, 19, 20]
            .into_iter()
            .filter(|c| d.take(*c))
            .collect();
        assert_eq!(taken, vec![0, 5, 12, 17]);
        d.set_step(2);
        let taken: Vec<u64> = (21..26).filter(|c| d.take(*c)).collect();
        assert_eq!(taken, vec![22, 24]);
    }

    /// Samples a period apart are stamped exactly a period apart, whatever their readings'
    /// delays; the zero moves back only where a sample is missing, by at most 50 µs.
    #[test]
    fn the_clock_keeps_the_period() {
        let mut c = Clock::new(10_000);
        let zero = 1_000_000_000_000;
        // Read 3 ms late, then 1 ms late: the zero stays (no room between them).
        assert_eq!(c.stamp(10_000, zero + 10_000 + 30_000), zero + 40_000);
        assert_eq!(c.stamp(20_000, zero + 20_000 + 10_000), zero + 50_000);
        // Two samples missing: 20 000 ticks of room, of which 500 taken.
        assert_eq!(c.stamp(50_000, zero + 50_000), zero + 50_000 + 30_000 - 500);
        assert_eq!(c.zero(), Some(zero + 29_500));
        // A restarted machine: its time is a second off, the zero is taken afresh.
        assert_eq!(c.stamp(10_000, zero + 900_000_000), zero + 900_000_000);
    }
}
