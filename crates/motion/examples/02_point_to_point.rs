//! The trajectory generator (OTG) alone: a time-optimal, jerk-limited move of one axis
//! from rest at 0 to rest at 6 mm (the seeds' experiment 1: 50 mm/s, 1000 mm/s²,
//! 10 000 mm/s³), sampled every millisecond as a servo loop would, then three axes
//! synchronised to finish together. `cargo run -p rtcnc-motion --example 02_point_to_point`

use rtcnc_motion::otg::{Limits, State, position_profile, synchronize};

fn main() -> Result<(), rtcnc_motion::otg::OtgError> {
    let limits = Limits::symmetric(50.0, 1000.0, 10_000.0);
    let profile = position_profile(
        State::new(0.0, 0.0, 0.0),
        State::new(6.0, 0.0, 0.0),
        &limits,
    )?;
    println!("one axis: {:.4} s", profile.duration());
    let period = 0.001;
    let mut t = 0.0;
    while t < profile.duration() + period {
        let s = profile.at(t);
        if (t / period).round() as u64 % 50 == 0 {
            println!(
                "  t={t:.3} s  p={:8.4} mm  v={:7.3} mm/s  a={:8.2} mm/s²",
                s.p, s.v, s.a
            );
        }
        t += period;
    }

    // Three axes from rest to rest, each with its own distance: the longest sets the
    // duration, the others are slowed to end with it.
    let starts = [State::new(0.0, 0.0, 0.0); 3];
    let targets = [
        State::new(6.0, 0.0, 0.0),
        State::new(-2.0, 0.0, 0.0),
        State::new(0.5, 0.0, 0.0),
    ];
    let sync = synchronize(&starts, &targets, &[limits; 3])?;
    println!("three axes, synchronised: {:.4} s", sync.duration());
    Ok(())
}
