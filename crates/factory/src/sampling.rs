//! The node manager of the machine's instance nodes: an in-memory address space that also
//! keeps the sampling interval of every monitored item on those nodes, so the values are
//! read from the machine as often as the fastest of them asks, and no faster.

use std::collections::HashMap;
use std::sync::Mutex;

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
use opcua::types::{MonitoringMode, StatusCode, TimestampsToReturn};
use tokio::sync::watch;

/// The machine's node manager.
pub type MachineNodeManager = InMemoryNodeManager<MachineNodes>;

/// No monitored item samples (or none asks for an interval of its own).
pub const NOBODY_SAMPLES: f64 = f64::INFINITY;

/// The in-memory nodes of the machine and the sampling intervals asked of them.
pub struct MachineNodes {
    name: String,
    namespaces: Vec<NamespaceMetadata>,
    /// Sampling interval (ms) of each sampling monitored item.
    intervals: Mutex<HashMap<MonitoredItemHandle, f64>>,
    /// Monitored items that exist, sampling or not, with their interval.
    known: Mutex<HashMap<MonitoredItemHandle, f64>>,
    fastest: watch::Sender<f64>,
}

impl MachineNodes {
    /// Publishes the fastest interval asked for, when it changed.
    fn update(&self, intervals: &HashMap<MonitoredItemHandle, f64>) {
        let fastest = fastest_interval(intervals.values().copied());
        self.fastest.send_if_modified(|f| {
            let changed = *f != fastest;
            *f = fastest;
            changed
        });
    }

    fn lock(
        m: &Mutex<HashMap<MonitoredItemHandle, f64>>,
    ) -> std::sync::MutexGuard<'_, HashMap<MonitoredItemHandle, f64>> {
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

/// A builder of the machine's node manager in `namespace_uri`; `fastest` receives the
/// fastest sampling interval (ms) any of its monitored items asks for.
pub fn machine_node_manager(
    namespace_uri: String,
    name: &str,
    fastest: watch::Sender<f64>,
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
                fastest,
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
            known.insert(item.handle(), item.sampling_interval());
            if item.monitoring_mode() != MonitoringMode::Disabled {
                intervals.insert(item.handle(), item.sampling_interval());
            }
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
            known.insert(it.handle(), interval);
            if let Some(i) = intervals.get_mut(&it.handle()) {
                *i = interval;
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
                    intervals.insert(it.handle(), *i);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fastest_interval_ignores_the_subscription_default() {
        assert_eq!(fastest_interval([].into_iter()), NOBODY_SAMPLES);
        assert_eq!(fastest_interval([-1.0].into_iter()), NOBODY_SAMPLES);
        assert_eq!(fastest_interval([100.0, 1.0, -1.0, 10.0].into_iter()), 1.0);
    }
}
