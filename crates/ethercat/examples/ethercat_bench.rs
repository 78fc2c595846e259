//! The master's cyclic exchange measured over a network interface, for bench/ethercat.sh:
//! `drives` simulated CSP drives and a DIO terminal (the simulator's identities), enabled
//! and moving, at a 1 ms cycle aligned to SYNC0, for a number of seconds. Prints cycles,
//! working-counter errors and lost frames, the frames' round trip, the master's CPU time
//! per exchange and the wake-up latency of the cycle thread.
//!
//! ```text
//! ethercat_bench --interface m0 [--drives 12] [--seconds 600] [--priority 80]
//! ```

use std::time::Duration;

use rtcnc_ecat_slave_sim::dio::DIO_PRODUCT_CODE;
use rtcnc_ecat_slave_sim::drive::{DRIVE_PRODUCT_CODE, SIMULATOR_VENDOR_ID};
use rtcnc_ethercat::clock::monotonic_ns;
use rtcnc_ethercat::{Clock, EthercatConfig, EthercatMaster};
use rtcnc_fieldbus::{ControlWord, Fieldbus, ProcessInputs, ProcessOutputs};

fn thread_cpu_ns() -> u64 {
    let mut spec = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: the timespec is valid for the call.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &raw mut spec) };
    spec.tv_sec as u64 * 1_000_000_000 + spec.tv_nsec as u64
}

/// Percentile `p` (0-100) of a histogram in 1 µs bins, in µs.
fn percentile(bins: &[u64], p: f64) -> usize {
    let total: u64 = bins.iter().sum();
    let rank = ((total as f64) * p / 100.0).ceil().max(1.0) as u64;
    let mut seen = 0;
    for (bin, &count) in bins.iter().enumerate() {
        seen += count;
        if seen >= rank {
            return bin;
        }
    }
    bins.len()
}

fn main() {
    let mut args = std::env::args().skip(1);
    let (mut interface, mut drives, mut seconds, mut priority) =
        (String::from("m0"), 12usize, 600u64, 80i32);
    while let Some(arg) = args.next() {
        let value = args.next().unwrap_or_default();
        match arg.as_str() {
            "--interface" => interface = value,
            "--drives" => drives = value.parse().expect("--drives N"),
            "--seconds" => seconds = value.parse().expect("--seconds N"),
            "--priority" => priority = value.parse().expect("--priority N"),
            _ => {
                eprintln!(
                    "usage: ethercat_bench --interface NAME [--drives N] [--seconds N] [--priority N]"
                );
                std::process::exit(2);
            }
        }
    }
    let mut text = format!("interface = \"{interface}\"\n");
    for joint in 0..drives {
        text.push_str(&format!(
            "[[slaves]]\nkind = \"cia402\"\nname = \"J{joint}\"\nvendor_id = {SIMULATOR_VENDOR_ID}\nproduct_code = {DRIVE_PRODUCT_CODE}\nrevision = 0x00010000\njoint = {joint}\ncounts_per_unit = 26214.4\n"
        ));
    }
    text.push_str(&format!(
        "[[slaves]]\nkind = \"dio\"\nname = \"IO\"\nvendor_id = {SIMULATOR_VENDOR_ID}\nproduct_code = {DIO_PRODUCT_CODE}\nrevision = 0x00010000\n"
    ));
    let config: EthercatConfig = toml::from_str(&text).expect("configuration");

    // Real-time where allowed: memory locked, SCHED_FIFO.
    // SAFETY: plain syscalls with valid arguments.
    let locked = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0;
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: as above.
    let fifo = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &raw const param) } == 0;
    println!(
        "cycle thread: {}, memory {}",
        if fifo {
            format!("SCHED_FIFO {priority}")
        } else {
            "SCHED_OTHER (SCHED_FIFO refused)".into()
        },
        if locked { "locked" } else { "not locked" }
    );

    let period = Duration::from_millis(1);
    let mut master = EthercatMaster::start(&config, period).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1);
    });
    let mut outputs = ProcessOutputs::new(master.layout());
    let mut inputs = ProcessInputs::new(master.layout());
    let cycles = seconds * 1000;
    let mut latency = vec![0u64; 20_001];
    let mut cpu = vec![0u64; 20_001];
    let (mut latency_max, mut cpu_max, mut cpu_total) = (0u64, 0u64, 0u64);
    let (mut failed, mut start) = (0u64, Vec::new());
    let mut next = monotonic_ns();
    for k in 0..cycles {
        let correction = master.cycle_phase_error_ns().unwrap_or(0) / 10;
        next += (1_000_000 - correction.clamp(-50_000, 50_000)) as u64;
        Clock::Monotonic.sleep_until(next);
        let woke = monotonic_ns().saturating_sub(next);
        latency_max = latency_max.max(woke);
        latency[((woke / 1000) as usize).min(20_000)] += 1;
        // Enable, then move every joint on a 10 mm, 1 Hz sine.
        let t = k as f64 * 1e-3;
        for (j, (command, feedback)) in outputs.joints.iter_mut().zip(&inputs.joints).enumerate() {
            if k < 200 {
                command.controlword = feedback.state().controlword_towards(true);
                command.target_position = feedback.position;
                if k == 199 {
                    start.push(feedback.position);
                }
            } else {
                let phase = 2.0 * std::f64::consts::PI * (t - 0.2);
                command.controlword = ControlWord::enable_operation();
                command.target_position = start.get(j).copied().unwrap_or(0.0) + 10.0 * phase.sin();
                command.velocity_offset = 10.0 * 2.0 * std::f64::consts::PI * phase.cos();
            }
        }
        let before = thread_cpu_ns();
        if master.exchange(1e-3, &outputs, &mut inputs).is_err() {
            failed += 1;
        }
        let spent = thread_cpu_ns() - before;
        cpu_total += spent;
        cpu_max = cpu_max.max(spent);
        cpu[((spent / 1000) as usize).min(20_000)] += 1;
    }
    let stats = master.statistics();
    let (round_trips, longest) = master.round_trips().unwrap_or_default();
    let round_trips: Vec<u64> = round_trips.into_iter().map(u64::from).collect();
    println!("cycles                 {}", stats.cycles);
    println!("working counter errors {}", stats.working_counter_errors);
    println!("lost frames            {}", stats.lost_frames);
    println!("failed exchanges       {failed}");
    println!(
        "frame round trip       p50 {} µs  p99 {} µs  max {:.0} µs",
        percentile(&round_trips, 50.0),
        percentile(&round_trips, 99.0),
        longest as f64 / 1000.0
    );
    println!(
        "master CPU per cycle   mean {:.1} µs  p99 {} µs  max {:.0} µs",
        cpu_total as f64 / cycles.max(1) as f64 / 1000.0,
        percentile(&cpu, 99.0),
        cpu_max as f64 / 1000.0
    );
    println!(
        "wake-up latency        p50 {} µs  p99 {} µs  max {} µs",
        percentile(&latency, 50.0),
        percentile(&latency, 99.0),
        latency_max / 1000
    );
}
