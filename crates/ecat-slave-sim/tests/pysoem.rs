//! An independent master: SOEM through pysoem (PyPI) scans the simulator process over a
//! veth pair, reads identity and EEPROM, reads and writes SDOs and takes it to OP with
//! process data, and latches a drive's index through its touch probe (0x60B8-0x60BA)
//! (tests/pysoem_check.py). It catches errors that rtcnc's master and its simulator could
//! share.

mod support;

use std::path::PathBuf;
use std::process::Command;

use rtcnc_ecat_slave_sim::dio::DIO_PRODUCT_CODE;
use rtcnc_ecat_slave_sim::drive::{DRIVE_PRODUCT_CODE, SIMULATOR_VENDOR_ID};

/// The Python that has pysoem: `RTCNC_PYSOEM_PYTHON`, else the venv scripts/setup.sh makes.
fn python() -> PathBuf {
    if let Some(path) = std::env::var_os("RTCNC_PYSOEM_PYTHON") {
        return path.into();
    }
    let home = std::env::var_os("HOME").unwrap_or_default();
    PathBuf::from(home).join(".cache/rtcnc/venv-ethercat/bin/python")
}

#[test]
fn pysoem_takes_the_simulator_to_op() {
    if support::inside() {
        return;
    }
    if let Some(reason) = support::namespaces_refused() {
        println!("skipped: {reason}");
        return;
    }
    let python = python();
    assert!(
        python.exists(),
        "{} missing: scripts/setup.sh installs pysoem",
        python.display()
    );
    assert!(support::run_inside("pysoem_inside_the_namespace"));
}

#[test]
#[ignore = "runs inside the namespace that pysoem_takes_the_simulator_to_op makes"]
fn pysoem_inside_the_namespace() {
    assert!(support::inside(), "run by pysoem_takes_the_simulator_to_op");
    support::veth();
    let drives = 3;
    let _simulator = support::Simulator::start(&format!(
        "[[slaves]]\nkind = \"csp_drive\"\ncount = {drives}\n\
         [slaves.drive.joint]\ndrive = \"csp\"\nindex_offset = 0.3\n\
         [[slaves]]\nkind = \"dio\"\n"
    ));
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/pysoem_check.py");
    let status = Command::new(python())
        .arg(script)
        .arg(support::MASTER_END)
        .arg(drives.to_string())
        .arg(SIMULATOR_VENDOR_ID.to_string())
        .arg(DRIVE_PRODUCT_CODE.to_string())
        .arg(DIO_PRODUCT_CODE.to_string())
        .status()
        .expect("python runs");
    assert!(status.success(), "pysoem check failed");
}
