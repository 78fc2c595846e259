//! `rtcnc-factory`: the machine in the factory's networks. An OPC UA server with the CNC
//! companion model (OPC 40502) and an MQTT publisher, both inside the API process over the
//! API's connection to the machine (the machine process never waits on them).
//! docs/opcua.md and docs/mqtt.md describe them.
// Axis-indexed arrays read best with the axis index.
#![allow(clippy::needless_range_loop)]

use std::sync::Arc;

pub mod cnc;
pub mod config;
pub mod mqtt;
pub mod nodeset;
pub mod opcua_server;
pub mod sampling;
pub mod trace;

pub use config::FactoryConfig;

/// Starts what the machine file enables; called inside the API server's runtime.
pub fn start(app: Arc<rtcnc_api::App>) -> anyhow::Result<()> {
    let config = FactoryConfig::from_machine(&app.config)?;
    if let Some(section) = config.opcua {
        let app = Arc::clone(&app);
        // Binding and building happen on the runtime; a failure ends the API process with
        // the reason, as a port in use does for the API itself.
        tokio::task::block_in_place(|| {
            tokio::runtime::Handle::current().block_on(opcua_server::start(app, section))
        })?;
    }
    if let Some(section) = config.mqtt {
        mqtt::start(app, section)?;
    }
    Ok(())
}
