//! The committed OpenAPI document (docs/openapi.json) is the one this code generates: the
//! web HMI and the Python client's models are built from it.

#[test]
fn the_committed_openapi_document_is_current() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/openapi.json");
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    let generated = rtcnc_api::openapi_json();
    assert!(
        committed == generated,
        "docs/openapi.json is stale: regenerate it with\n  cargo run -p rtcnc -- api --print-openapi > docs/openapi.json\n\
         and the Python models with scripts/gen-python-models.sh"
    );
    let doc: serde_json::Value = serde_json::from_str(&generated).unwrap();
    assert_eq!(doc["openapi"], "3.1.0");
    // Every route of the router is documented.
    for path in [
        "/api/status",
        "/api/ws",
        "/api/events",
        "/api/control/estop",
        "/api/control/jog/keep-alive",
        "/api/programs/{name}/estimate",
        "/api/setup/tools",
        "/api/plc/force",
        "/api/diagnostics/trace",
    ] {
        assert!(doc["paths"].get(path).is_some(), "{path} is not documented");
    }
}
