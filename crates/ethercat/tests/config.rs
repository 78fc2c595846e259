//! The configuration: the example of docs/ethercat.md parses as the machine file's
//! `[fieldbus]` section, and refusals name the key.

use rtcnc_ethercat::{EthercatConfig, SlaveConfig};

fn docs_example() -> toml::Table {
    let text = include_str!("../../../docs/ethercat.md");
    let start = text.find("```toml\n[fieldbus]").expect("example") + "```toml\n".len();
    let end = start + text[start..].find("```").expect("end of example");
    toml::from_str(&text[start..end]).expect("example is TOML")
}

fn fieldbus_section(table: &toml::Table) -> EthercatConfig {
    let mut section = table["fieldbus"].as_table().expect("[fieldbus]").clone();
    assert_eq!(
        section
            .remove("kind")
            .and_then(|k| k.as_str().map(String::from))
            .as_deref(),
        Some("ethercat")
    );
    section.try_into().expect("EthercatConfig")
}

#[test]
fn the_documented_example_parses_and_validates() {
    let config = fieldbus_section(&docs_example());
    config.validate().expect("valid");
    assert_eq!(config.interface, "enp3s0");
    assert_eq!(config.estop_input, Some(7));
    assert_eq!(config.slaves.len(), 2);
    let SlaveConfig::Cia402 {
        counts_per_unit,
        sdo,
        rx_pdo,
        ..
    } = &config.slaves[0]
    else {
        panic!("a drive first");
    };
    assert_eq!(*counts_per_unit, 26214.4);
    assert_eq!(sdo[0].index, 0x6091);
    assert_eq!(rx_pdo, &rtcnc_ethercat::pdo::RxObject::CSP_DEFAULT);
}

#[test]
fn refusals_name_the_key() {
    let base = fieldbus_section(&docs_example());
    let mut two_on_one_joint = base.clone();
    two_on_one_joint
        .slaves
        .push(two_on_one_joint.slaves[0].clone());
    assert_eq!(
        two_on_one_joint.validate().unwrap_err().key,
        "slaves[2].joint"
    );

    let mut table = docs_example();
    table["fieldbus"]["slaves"][0]
        .as_table_mut()
        .unwrap()
        .insert(
            "rx_pdo".into(),
            toml::Value::Array(vec!["controlword".into()]),
        );
    let config = fieldbus_section(&table);
    let error = config.validate().unwrap_err();
    assert_eq!(error.key, "slaves[0].rx_pdo");
    assert!(error.reason.contains("target_position"), "{error}");

    let mut table = docs_example();
    table["fieldbus"]
        .as_table_mut()
        .unwrap()
        .insert("unknown_key".into(), 1.into());
    let mut section = table["fieldbus"].as_table().unwrap().clone();
    section.remove("kind");
    let error = section.try_into::<EthercatConfig>().unwrap_err();
    assert!(error.to_string().contains("unknown_key"), "{error}");
}
