//! The machine file's `[opcua]` and `[mqtt]` sections (the kernel keeps them as raw tables:
//! the machine process does not use them).

use std::net::SocketAddr;
use std::path::PathBuf;

use rtcnc_kernel::MachineConfig;
use serde::Deserialize;

/// A section that does not read.
#[derive(Debug, thiserror::Error)]
#[error("[{section}]: {message}")]
pub struct ConfigError {
    /// `opcua` or `mqtt`.
    pub section: &'static str,
    /// What is wrong, naming the key.
    pub message: String,
}

/// `[opcua]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpcUaSection {
    /// The server runs (the section alone does not start it).
    #[serde(default)]
    pub enabled: bool,
    /// Address and port (4840 is OPC UA's registered port).
    #[serde(default = "OpcUaSection::default_listen")]
    pub listen: SocketAddr,
    /// Host name put in the endpoint URLs (default: the listen address).
    #[serde(default)]
    pub host_name: Option<String>,
    /// Folder of the server's certificate, private key, trusted and rejected client
    /// certificates (default `opcua-pki/` beside the machine file).
    #[serde(default)]
    pub pki: Option<PathBuf>,
    /// Anonymous sessions (read only). Off unless asked for.
    #[serde(default)]
    pub anonymous: bool,
    /// An endpoint without signing or encryption besides the secure ones (user names and
    /// passwords are still encrypted with the server's certificate).
    #[serde(default)]
    pub allow_unsecured: bool,
    /// Accept client certificates that are not in `pki/trusted` (a test bench's choice;
    /// otherwise an unknown client's certificate lands in `pki/rejected` to be moved).
    #[serde(default)]
    pub trust_all_clients: bool,
    /// Fastest publishing interval offered, ms (sampling goes down to the servo period).
    #[serde(default = "OpcUaSection::default_min_interval_ms")]
    pub min_interval_ms: f64,
    /// Largest number of sessions at once.
    #[serde(default = "OpcUaSection::default_max_sessions")]
    pub max_sessions: usize,
    /// umati identification (OPC 40001-1): manufacturer. With `serial_number`, the machine
    /// appears in the Machines folder.
    #[serde(default)]
    pub manufacturer: Option<String>,
    /// Model.
    #[serde(default)]
    pub model: Option<String>,
    /// Serial number.
    #[serde(default)]
    pub serial_number: Option<String>,
    /// Year of construction.
    #[serde(default)]
    pub year_of_construction: Option<u16>,
}

impl OpcUaSection {
    fn default_listen() -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], 4840))
    }
    fn default_min_interval_ms() -> f64 {
        10.0
    }
    fn default_max_sessions() -> usize {
        100
    }
}

/// `[mqtt]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MqttSection {
    /// The publisher runs.
    #[serde(default)]
    pub enabled: bool,
    /// The broker's host name or address.
    pub host: String,
    /// Its port (default 1883, 8883 with TLS).
    #[serde(default)]
    pub port: Option<u16>,
    /// Client identifier (default `rtcnc-` and the topic's machine part).
    #[serde(default)]
    pub client_id: Option<String>,
    /// Topic prefix (default `rtcnc/<machine name, lower case, spaces as ->`).
    #[serde(default)]
    pub topic_prefix: Option<String>,
    /// Positions and overrides per second.
    #[serde(default = "MqttSection::default_rate_hz")]
    pub rate_hz: f64,
    /// User name.
    #[serde(default)]
    pub username: Option<String>,
    /// A file holding the password (its first line), relative to the machine file: the
    /// machine file itself is readable over the API.
    #[serde(default)]
    pub password_file: Option<PathBuf>,
    /// TLS to the broker.
    #[serde(default)]
    pub tls: bool,
    /// CA certificate(s), PEM, that the broker's certificate must chain to.
    #[serde(default)]
    pub ca_certificate: Option<PathBuf>,
    /// Client certificate and key (PEM) for brokers that ask for one.
    #[serde(default)]
    pub client_certificate: Option<PathBuf>,
    /// Its key.
    #[serde(default)]
    pub client_key: Option<PathBuf>,
    /// Alarms and messages kept while the broker is away; beyond it the oldest are dropped
    /// and counted in the next `alarm`.
    #[serde(default = "MqttSection::default_queue")]
    pub queue: usize,
    /// Seconds between keep-alive pings.
    #[serde(default = "MqttSection::default_keep_alive_s")]
    pub keep_alive_s: u64,
}

impl MqttSection {
    fn default_rate_hz() -> f64 {
        10.0
    }
    fn default_queue() -> usize {
        10_000
    }
    fn default_keep_alive_s() -> u64 {
        5
    }
}

/// Both sections, checked.
#[derive(Debug, Clone, Default)]
pub struct FactoryConfig {
    /// `[opcua]` with `enabled = true`.
    pub opcua: Option<OpcUaSection>,
    /// `[mqtt]` with `enabled = true`.
    pub mqtt: Option<MqttSection>,
}

impl FactoryConfig {
    /// Reads and checks the sections of a loaded machine file.
    pub fn from_machine(config: &MachineConfig) -> Result<FactoryConfig, ConfigError> {
        let opcua = match &config.opcua {
            Some(t) => Some(parse::<OpcUaSection>("opcua", t)?),
            None => None,
        };
        let mqtt = match &config.mqtt {
            Some(t) => Some(parse::<MqttSection>("mqtt", t)?),
            None => None,
        };
        if let Some(o) = &opcua {
            if !(o.min_interval_ms.is_finite() && (1.0..=60_000.0).contains(&o.min_interval_ms)) {
                return Err(ConfigError {
                    section: "opcua",
                    message: "min_interval_ms: from 1 to 60000".into(),
                });
            }
            if o.max_sessions == 0 || o.max_sessions > 10_000 {
                return Err(ConfigError {
                    section: "opcua",
                    message: "max_sessions: from 1 to 10000".into(),
                });
            }
        }
        if let Some(m) = &mqtt {
            let bad = |message: &str| ConfigError {
                section: "mqtt",
                message: message.into(),
            };
            if !(m.rate_hz.is_finite() && m.rate_hz > 0.0 && m.rate_hz <= 1000.0) {
                return Err(bad("rate_hz: above 0, at most 1000"));
            }
            if m.host.trim().is_empty() {
                return Err(bad("host: empty"));
            }
            if m.queue == 0 || m.queue > 1_000_000 {
                return Err(bad("queue: from 1 to 1000000"));
            }
            if m.keep_alive_s == 0 || m.keep_alive_s > 3600 {
                return Err(bad("keep_alive_s: from 1 to 3600"));
            }
            if m.client_certificate.is_some() != m.client_key.is_some() {
                return Err(bad("client_certificate and client_key go together"));
            }
            if (m.client_certificate.is_some() || m.ca_certificate.is_some()) && !m.tls {
                return Err(bad("certificates are given but tls is false"));
            }
            if m.password_file.is_some() && m.username.is_none() {
                return Err(bad("password_file without username"));
            }
            if let Some(p) = &m.topic_prefix {
                if p.is_empty() || p.contains(['+', '#']) || p.ends_with('/') {
                    return Err(bad(
                        "topic_prefix: not empty, no '+' or '#', not ending with '/'",
                    ));
                }
            }
        }
        Ok(FactoryConfig {
            opcua: opcua.filter(|o| o.enabled),
            mqtt: mqtt.filter(|m| m.enabled),
        })
    }
}

fn parse<T: serde::de::DeserializeOwned>(
    section: &'static str,
    table: &toml::Table,
) -> Result<T, ConfigError> {
    toml::Value::Table(table.clone())
        .try_into()
        .map_err(|e: toml::de::Error| ConfigError {
            section,
            message: e.message().to_string(),
        })
}

/// The machine name as a topic or identifier part: lower case, runs of anything but
/// letters and digits as one `-`.
pub fn slug(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('-') && !out.is_empty() {
            out.push('-');
        }
    }
    while out.ends_with('-') {
        out.pop();
    }
    if out.is_empty() {
        "machine".into()
    } else {
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn machine(extra: &str) -> Result<FactoryConfig, String> {
        let mill = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/sim-mill.toml"
        ))
        .unwrap();
        let dir = std::env::temp_dir().join(format!("rtcnc-factory-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let text = mill.replace(
            "program = \"../examples/plc/mill.st\"",
            &format!(
                "program = \"{}/../../examples/plc/mill.st\"",
                env!("CARGO_MANIFEST_DIR")
            ),
        ) + extra;
        // Tests run in parallel: a file each.
        static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = dir.join(format!("m{n}.toml"));
        std::fs::write(&path, text).unwrap();
        std::fs::copy(
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs/sim-mill.tbl"),
            dir.join("sim-mill.tbl"),
        )
        .unwrap();
        let config = MachineConfig::load(&path).map_err(|e| e.to_string())?;
        FactoryConfig::from_machine(&config).map_err(|e| e.to_string())
    }

    #[test]
    fn absent_sections_start_nothing() {
        let c = machine("").unwrap();
        assert!(c.opcua.is_none() && c.mqtt.is_none());
    }

    #[test]
    fn a_section_needs_enabled() {
        let c = machine("\n[opcua]\nanonymous = false\n").unwrap();
        assert!(c.opcua.is_none());
        let c = machine("\n[opcua]\nenabled = true\n").unwrap();
        let o = c.opcua.unwrap();
        assert!(!o.anonymous, "anonymous access is off by default");
        assert!(!o.allow_unsecured && !o.trust_all_clients);
        assert_eq!(o.listen, "127.0.0.1:4840".parse().unwrap());
    }

    #[test]
    fn unknown_keys_and_bad_values_are_refused_with_the_key() {
        let e = machine("\n[opcua]\nenabled = true\nanonymus = true\n").unwrap_err();
        assert!(e.contains("anonymus"), "{e}");
        let e = machine("\n[mqtt]\nenabled = true\nhost = \"b\"\nrate_hz = 0\n").unwrap_err();
        assert!(e.contains("rate_hz"), "{e}");
        let e = machine("\n[mqtt]\nenabled = true\nhost = \"b\"\ntopic_prefix = \"a/#\"\n")
            .unwrap_err();
        assert!(e.contains("topic_prefix"), "{e}");
        let e = machine("\n[mqtt]\nenabled = true\nhost = \"b\"\nca_certificate = \"ca.pem\"\n")
            .unwrap_err();
        assert!(e.contains("tls"), "{e}");
        let e = machine("\n[mqtt]\nenabled = true\n").unwrap_err();
        assert!(e.contains("host"), "{e}");
    }

    #[test]
    fn slugs() {
        assert_eq!(slug("Simulated 3-axis mill"), "simulated-3-axis-mill");
        assert_eq!(slug("  ÄÖ "), "machine");
        assert_eq!(slug("Lathe #2"), "lathe-2");
    }
}
