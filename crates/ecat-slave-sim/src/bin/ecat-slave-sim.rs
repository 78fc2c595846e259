//! The EtherCAT slave simulator as a process: a segment of simulated devices answering
//! on a network interface (one end of a veth pair, typically), in real time.
//!
//! ```text
//! ecat-slave-sim --interface s0 --config segment.toml [--priority 70]
//! ```
//!
//! `--priority` asks for SCHED_FIFO at that priority (and locked memory), so that the
//! simulated devices answer like hardware even on a loaded machine; refused without the
//! right to it, which is then printed.
//!
//! Prints `ready` once the interface is open. Faults come as lines on standard input:
//!
//! ```text
//! loss 0.05                 lose 5 % of the frames (0 to stop)
//! safeop 3 0x001a           device 3 falls to SAFE-OP with AL status code 0x001A
//! drive-fault 2 0x2310      drive 2 faults with error code 0x2310
//! drive-clear 2             the cause of drive 2's fault goes away
//! pd-loss 4 | pd-clear 4    device 4 stops (resumes) serving the process data
//! link down | link up       take the interface down (the master sees no carrier) or up
//! stats                     print frames seen and lost
//! quit                      end
//! ```

use std::io::BufRead;
use std::sync::mpsc;
use std::time::Duration;

use rtcnc_ecat_slave_sim::raw_socket::RawSocket;
use rtcnc_ecat_slave_sim::{Fault, Outcome, SegmentConfig};

fn usage() -> ! {
    eprintln!("usage: ecat-slave-sim --interface NAME --config SEGMENT.toml [--priority N]");
    std::process::exit(2);
}

fn parse_number(text: &str) -> Option<u64> {
    match text.strip_prefix("0x") {
        Some(hex) => u64::from_str_radix(hex, 16).ok(),
        None => text.parse().ok(),
    }
}

/// A command line from standard input.
enum Command {
    Fault(Fault, bool),
    Link(bool),
    Stats,
    Quit,
}

fn parse_command(line: &str) -> Result<Command, String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let number = |n: usize| {
        words
            .get(n)
            .and_then(|w| parse_number(w))
            .ok_or_else(|| format!("`{line}`: expected a number in place {n}"))
    };
    match words.first().copied() {
        Some("loss") => {
            let rate: f64 = words
                .get(1)
                .and_then(|w| w.parse().ok())
                .ok_or_else(|| format!("`{line}`: expected a rate"))?;
            Ok(Command::Fault(Fault::FrameLoss { rate }, rate > 0.0))
        }
        Some("safeop") => Ok(Command::Fault(
            Fault::FallToSafeOp {
                slave: number(1)? as usize,
                code: number(2)? as u16,
            },
            true,
        )),
        Some("drive-fault") => Ok(Command::Fault(
            Fault::DriveFault {
                slave: number(1)? as usize,
                error_code: number(2)? as u16,
            },
            true,
        )),
        Some("drive-clear") => Ok(Command::Fault(
            Fault::DriveFault {
                slave: number(1)? as usize,
                error_code: 0,
            },
            false,
        )),
        Some("pd-loss") => Ok(Command::Fault(
            Fault::ProcessDataLoss {
                slave: number(1)? as usize,
            },
            true,
        )),
        Some("pd-clear") => Ok(Command::Fault(
            Fault::ProcessDataLoss {
                slave: number(1)? as usize,
            },
            false,
        )),
        Some("link") => match words.get(1).copied() {
            Some("down") => Ok(Command::Link(false)),
            Some("up") => Ok(Command::Link(true)),
            _ => Err(format!("`{line}`: link down or link up")),
        },
        Some("stats") => Ok(Command::Stats),
        Some("quit") => Ok(Command::Quit),
        _ => Err(format!("`{line}`: unknown command")),
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let (mut interface, mut config_path, mut priority) = (None, None, None);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--interface" => interface = args.next(),
            "--config" => config_path = args.next(),
            "--priority" => priority = args.next().and_then(|p| p.parse::<i32>().ok()),
            _ => usage(),
        }
    }
    if let Some(priority) = priority {
        let param = libc::sched_param {
            sched_priority: priority,
        };
        // SAFETY: plain syscalls with valid arguments.
        let fifo = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &raw const param) };
        // SAFETY: as above.
        let locked = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
        if fifo != 0 || locked != 0 {
            eprintln!("ecat-slave-sim: SCHED_FIFO {priority} or locked memory refused");
        }
    }
    let (Some(interface), Some(config_path)) = (interface, config_path) else {
        usage()
    };
    let text = std::fs::read_to_string(&config_path).unwrap_or_else(|e| {
        eprintln!("ecat-slave-sim: {config_path}: {e}");
        std::process::exit(1);
    });
    let config: SegmentConfig = toml::from_str(&text).unwrap_or_else(|e| {
        eprintln!("ecat-slave-sim: {config_path}: {e}");
        std::process::exit(1);
    });
    let mut segment = config.build().unwrap_or_else(|e| {
        eprintln!("ecat-slave-sim: {config_path}: {e}");
        std::process::exit(1);
    });
    let socket = RawSocket::open(&interface).unwrap_or_else(|e| {
        eprintln!("ecat-slave-sim: {interface}: {e} (a raw socket needs CAP_NET_RAW)");
        std::process::exit(1);
    });

    let (commands, incoming) = mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if line.trim().is_empty() {
                continue;
            }
            let command = parse_command(&line);
            if commands.send(command).is_err() {
                break;
            }
        }
        let _ = commands.send(Ok(Command::Quit));
    });

    println!("ready {} devices on {interface}", segment.slaves().len());
    let mut buffer = vec![0u8; 2048];
    let mut link_up = true;
    loop {
        while let Ok(command) = incoming.try_recv() {
            match command {
                Ok(Command::Fault(fault, active)) => {
                    let result = if active {
                        segment.inject(fault)
                    } else {
                        segment.clear(fault)
                    };
                    match result {
                        Ok(()) => println!("ok"),
                        Err(e) => println!("error: {e}"),
                    }
                }
                Ok(Command::Link(up)) => {
                    link_up = up;
                    match socket.set_up(up) {
                        Ok(()) => println!("ok"),
                        Err(e) => println!("error: {e}"),
                    }
                }
                Ok(Command::Stats) => println!(
                    "frames {} lost {} devices {}",
                    segment.frames,
                    segment.lost,
                    segment.slaves().len()
                ),
                Ok(Command::Quit) => return,
                Err(message) => println!("error: {message}"),
            }
        }
        let received = match socket.receive(&mut buffer, Some(Duration::from_millis(20))) {
            Ok(Some(len)) => len,
            Ok(None) => continue,
            Err(e) => {
                if link_up {
                    eprintln!("ecat-slave-sim: receive: {e}");
                }
                std::thread::sleep(Duration::from_millis(20));
                continue;
            }
        };
        let frame = &mut buffer[..received];
        // A reply already processed by a first device carries the locally administered
        // bit in its source address: not a request for this segment.
        if frame.get(6).is_some_and(|b| b & 0x02 != 0) {
            continue;
        }
        let now = rtcnc_ecat_slave_sim::raw_socket::monotonic_ns();
        match segment.process(frame, now) {
            Ok(Outcome::Returned) => {
                if let Err(e) = socket.send(frame) {
                    eprintln!("ecat-slave-sim: send: {e}");
                }
            }
            Ok(Outcome::Lost) => {}
            Err(e) => eprintln!("ecat-slave-sim: {e}"),
        }
    }
}
