//! The slave controller against the rules of ETG.1000.4 (datagram addressing and working
//! counter), ETG.1000.6 (AL state machine, SII interface) and the FMMU mapping, checked
//! with frames built by hand.

use rtcnc_ecat_slave_sim::esc::{AlState, reg};
use rtcnc_ecat_slave_sim::frame::{self, Command, DatagramSpan, read_u16};
use rtcnc_ecat_slave_sim::{Outcome, Segment, SegmentConfig};

fn segment(toml_text: &str) -> Segment {
    let config: SegmentConfig = toml::from_str(toml_text).expect("segment");
    config.build().expect("segment builds")
}

fn dio_segment(count: usize) -> Segment {
    segment(&format!("[[slaves]]\nkind = \"dio\"\ncount = {count}\n"))
}

/// Sends one frame with these datagrams; returns each datagram's data and working counter.
fn send(segment: &mut Segment, datagrams: &[(Command, u32, &[u8])]) -> Vec<(Vec<u8>, u16, u32)> {
    let list: Vec<(Command, u8, u32, &[u8])> = datagrams
        .iter()
        .enumerate()
        .map(|(n, (c, a, d))| (*c, n as u8, *a, *d))
        .collect();
    let mut buffer = vec![0u8; 1514];
    let len = frame::build(&mut buffer, [0x10; 6], &list).expect("frame fits");
    let frame = &mut buffer[..len];
    assert_eq!(
        segment.process(frame, 1_000_000).expect("valid"),
        Outcome::Returned
    );
    assert_eq!(
        frame[6], 0x12,
        "the reply's source address is locally administered"
    );
    let mut spans = [DatagramSpan {
        header: 0,
        data_len: 0,
    }; 8];
    let count = frame::datagrams(frame, &mut spans).expect("reply parses");
    spans[..count]
        .iter()
        .map(|s| {
            (
                frame[s.data()..s.data() + s.data_len].to_vec(),
                read_u16(frame, s.wkc()).unwrap(),
                frame::read_u32(frame, s.header + 2).unwrap(),
            )
        })
        .collect()
}

fn address(position_or_station: u16, offset: u16) -> u32 {
    u32::from(position_or_station) | (u32::from(offset) << 16)
}

#[test]
fn broadcast_read_counts_every_device_and_ors_their_data() {
    let mut bus = dio_segment(3);
    let reply = send(
        &mut bus,
        &[(Command::Brd, address(0, reg::TYPE as u16), &[0, 0])],
    );
    assert_eq!(reply[0].1, 3);
    assert_eq!(reply[0].0, vec![0x11, 0x00]);
}

#[test]
fn auto_increment_addresses_the_device_that_sees_zero_and_every_device_counts_up() {
    let mut bus = dio_segment(3);
    // Position 1 is addressed as 0xFFFF: the first device makes it 0.
    let reply = send(
        &mut bus,
        &[(Command::Apwr, address(0xFFFF, 0x0010), &[0x01, 0x10])],
    );
    assert_eq!(reply[0].1, 1);
    assert_eq!(
        reply[0].2 & 0xFFFF,
        0x0002,
        "three devices counted 0xFFFF up"
    );
    assert_eq!(bus.slaves()[1].station_address(), 0x1001);
    assert_eq!(bus.slaves()[0].station_address(), 0);
    // Configured-address read: only the device with that address answers.
    let reply = send(
        &mut bus,
        &[
            (Command::Fprd, address(0x1001, 0x0010), &[0, 0]),
            (Command::Fprd, address(0x2000, 0x0010), &[0, 0]),
        ],
    );
    assert_eq!((reply[0].0.clone(), reply[0].1), (vec![0x01, 0x10], 1));
    assert_eq!(reply[1].1, 0);
}

#[test]
fn a_read_write_counts_three() {
    let mut bus = dio_segment(2);
    send(
        &mut bus,
        &[(Command::Apwr, address(0, 0x0010), &[0x00, 0x10])],
    );
    let reply = send(
        &mut bus,
        &[(Command::Fprw, address(0x1000, 0x0012), &[0x34, 0x12])],
    );
    // The read returns the old alias, the write stores the new one.
    assert_eq!((reply[0].0.clone(), reply[0].1), (vec![0, 0], 3));
    let reply = send(
        &mut bus,
        &[(Command::Fprd, address(0x1000, 0x0012), &[0, 0])],
    );
    assert_eq!(reply[0].0, vec![0x34, 0x12]);
}

#[test]
fn al_control_walks_the_state_machine_and_refuses_a_skipped_state() {
    let mut bus = dio_segment(1);
    let set = |bus: &mut Segment, value: u16| {
        send(
            bus,
            &[(
                Command::Bwr,
                address(0, reg::AL_CONTROL as u16),
                &value.to_le_bytes(),
            )],
        )
    };
    set(&mut bus, 0x0004); // INIT -> SAFE-OP skips PRE-OP
    assert_eq!(bus.slaves()[0].al_status(), (AlState::Init, true, 0x0011));
    let reply = send(
        &mut bus,
        &[(Command::Brd, address(0, reg::AL_STATUS as u16), &[0, 0])],
    );
    assert_eq!(reply[0].0, vec![0x11, 0x00], "INIT with the error flag");
    set(&mut bus, 0x0002); // without acknowledging, the error holds the device
    assert_eq!(bus.slaves()[0].al_status(), (AlState::Init, true, 0x0011));
    set(&mut bus, 0x0012); // acknowledge and PRE-OP (no mailbox: nothing to check)
    assert_eq!(bus.slaves()[0].al_status(), (AlState::PreOp, false, 0));
    set(&mut bus, 0x0003); // BOOT is not offered
    assert_eq!(bus.slaves()[0].al_status(), (AlState::PreOp, true, 0x0013));
}

#[test]
fn the_eeprom_interface_reads_eight_bytes_and_the_header_crc_checks() {
    let mut bus = dio_segment(1);
    // Read command (bit 8) at word 0x0008: vendor ID and product code.
    send(
        &mut bus,
        &[
            (
                Command::Bwr,
                address(0, reg::SII_ADDRESS as u16),
                &[0x08, 0, 0, 0],
            ),
            (
                Command::Bwr,
                address(0, reg::SII_CONTROL as u16),
                &[0x00, 0x01],
            ),
        ],
    );
    let reply = send(
        &mut bus,
        &[
            (Command::Brd, address(0, reg::SII_CONTROL as u16), &[0, 0]),
            (Command::Brd, address(0, reg::SII_DATA as u16), &[0; 8]),
        ],
    );
    let control = u16::from_le_bytes([reply[0].0[0], reply[0].0[1]]);
    assert_eq!(control & 0x8040, 0x0040, "8-byte reads, not busy");
    let vendor = u32::from_le_bytes(reply[1].0[0..4].try_into().unwrap());
    let product = u32::from_le_bytes(reply[1].0[4..8].try_into().unwrap());
    assert_eq!((vendor, product), (0x0E5C, 0x0808));
    assert!(bus.slaves()[0].sii().header_crc_valid());
}

/// Takes DIO terminals to SAFE-OP with their process data sync managers and FMMUs set as
/// a master does: outputs at logical 0x10000 + 2n, inputs at 0x10001 + 2n.
fn dio_in_safe_op(count: usize) -> Segment {
    let mut bus = dio_segment(count);
    for n in 0..count {
        let station = 0x1000 + n as u16;
        let position = (n as u16).wrapping_neg();
        send(
            &mut bus,
            &[(
                Command::Apwr,
                address(position, 0x0010),
                &station.to_le_bytes(),
            )],
        );
        let logical = 0x10000 + 2 * n as u32;
        let mut fmmu0 = [0u8; 16];
        fmmu0[0..4].copy_from_slice(&logical.to_le_bytes());
        fmmu0[4..6].copy_from_slice(&1u16.to_le_bytes());
        fmmu0[7] = 7;
        fmmu0[8..10].copy_from_slice(&0x1000u16.to_le_bytes());
        fmmu0[11] = 0x02; // write
        fmmu0[12] = 1;
        let mut fmmu1 = fmmu0;
        fmmu1[0..4].copy_from_slice(&(logical + 1).to_le_bytes());
        fmmu1[8..10].copy_from_slice(&0x1100u16.to_le_bytes());
        fmmu1[11] = 0x01; // read
        let sm0 = [0x00, 0x10, 1, 0, 0x44, 0, 1, 0];
        let sm1 = [0x00, 0x11, 1, 0, 0x00, 0, 1, 0];
        send(
            &mut bus,
            &[
                (Command::Fpwr, address(station, 0x0600), &fmmu0),
                (Command::Fpwr, address(station, 0x0610), &fmmu1),
                (Command::Fpwr, address(station, 0x0800), &sm0),
                (Command::Fpwr, address(station, 0x0808), &sm1),
                (
                    Command::Fpwr,
                    address(station, reg::AL_CONTROL as u16),
                    &[2, 0],
                ),
                (
                    Command::Fpwr,
                    address(station, reg::AL_CONTROL as u16),
                    &[4, 0],
                ),
            ],
        );
        assert_eq!(bus.slaves()[n].al_status(), (AlState::SafeOp, false, 0));
    }
    bus
}

#[test]
fn logical_read_write_counts_one_per_read_and_two_per_write_fmmu() {
    let mut bus = dio_in_safe_op(2);
    let reply = send(&mut bus, &[(Command::Lrw, 0x10000, &[0xAA, 0, 0x55, 0])]);
    assert_eq!(reply[0].1, 6, "two devices, each read (1) and write (2)");
    let reply = send(&mut bus, &[(Command::Lrd, 0x10000, &[0, 0, 0, 0])]);
    assert_eq!(reply[0].1, 2, "a logical read counts the read FMMUs only");
    let reply = send(&mut bus, &[(Command::Lwr, 0x10002, &[0x0F, 0])]);
    assert_eq!(
        reply[0].1, 2,
        "a logical write reaching one device's write FMMU"
    );
    // Outside every FMMU: nobody counts.
    let reply = send(&mut bus, &[(Command::Lrw, 0x20000, &[0, 0])]);
    assert_eq!(reply[0].1, 0);
}

#[test]
fn a_bitwise_fmmu_moves_single_bits() {
    let mut bus = dio_in_safe_op(1);
    // Bits 0-3 of the inputs byte to bits 4-7 of logical byte 0x30000.
    let mut fmmu = [0u8; 16];
    fmmu[0..4].copy_from_slice(&0x30000u32.to_le_bytes());
    fmmu[4..6].copy_from_slice(&1u16.to_le_bytes());
    fmmu[6] = 4;
    fmmu[7] = 7;
    fmmu[8..10].copy_from_slice(&0x1100u16.to_le_bytes());
    fmmu[10] = 0;
    fmmu[11] = 0x01;
    fmmu[12] = 1;
    send(&mut bus, &[(Command::Fpwr, address(0x1000, 0x0620), &fmmu)]);
    // Put 0b1001_0110 in the inputs buffer as the device would.
    let mut bus_inputs = bus;
    {
        let slave = bus_inputs.slave_mut(0).unwrap();
        let terminal = slave
            .application_mut()
            .as_any_mut()
            .downcast_mut::<rtcnc_ecat_slave_sim::dio::DioTerminal>()
            .unwrap();
        terminal.set_inputs(0b1001_0110);
    }
    // An outputs write runs the free-running terminal's cycle, which samples the inputs.
    send(&mut bus_inputs, &[(Command::Lwr, 0x10000, &[0])]);
    let reply = send(&mut bus_inputs, &[(Command::Lrd, 0x30000, &[0x0A])]);
    assert_eq!(reply[0].1, 1);
    assert_eq!(
        reply[0].0,
        vec![0x6A],
        "low nibble kept, bits 0-3 of 0x96 in bits 4-7"
    );
}

#[test]
fn frmw_distributes_the_reference_time_one_read_and_a_write_per_other_device() {
    let mut bus = dio_segment(3);
    for n in 0..3u16 {
        send(
            &mut bus,
            &[(
                Command::Apwr,
                address(n.wrapping_neg(), 0x0010),
                &(0x1000 + n).to_le_bytes(),
            )],
        );
    }
    let reply = send(
        &mut bus,
        &[(
            Command::Frmw,
            address(0x1000, reg::DC_SYSTEM_TIME as u16),
            &[0; 8],
        )],
    );
    assert_eq!(reply[0].1, 3);
    let reference = bus.slaves()[0].system_time(1_000_000);
    let read = u64::from_le_bytes(reply[0].0.clone().try_into().unwrap());
    assert_eq!(
        read, reference,
        "the reference's time at the frame's arrival"
    );
}
