"""An independent master (SOEM, through pysoem) against the EtherCAT slave simulator.

Run by tests/pysoem.rs (rtcnc-ecat-slave-sim) inside a network namespace, on the master's end of a veth pair
whose other end the simulator serves with DRIVES CSP drives and one DIO terminal.
Usage: pysoem_check.py INTERFACE DRIVES VENDOR DRIVE_PRODUCT DIO_PRODUCT

Everything checked here is what SOEM reads and writes by itself: the identity and the
EEPROM, SDO uploads and downloads (expedited, normal, segmented) and an abort, the PDO
mapping it reads over CoE and from the EEPROM, the state machine to OP, and cyclic process
data with the working counter and a CiA 402 drive walked to operation enabled; drive 0's
PDOs carry its touch probe (0x60B8 out, 0x60B9 and 0x60BA in), armed on its encoder's
index (0x0015, CiA 402: enable, zero impulse, positive edge) while it moves over the index
at 0.3 mm: 0x60B9 reads 0x0043 (enabled, positive value stored, toggle) and 0x60BA
floor(0.3 x 131072 / 5) = 7864 increments.
"""

import struct
import sys
import time

import pysoem

interface = sys.argv[1]
drives = int(sys.argv[2])
vendor, drive_product, dio_product = (int(a, 0) for a in sys.argv[3:6])


def check(condition, message):
    if not condition:
        print("FAILED:", message)
        sys.exit(1)
    print("ok:", message)


master = pysoem.Master()
master.open(interface)
found = master.config_init()
check(found == drives + 1, f"{found} devices found, {drives + 1} expected")

for position, slave in enumerate(master.slaves):
    product = drive_product if position < drives else dio_product
    check(
        (slave.man, slave.id, slave.rev) == (vendor, product, 0x00010000),
        f"device {position} identity {slave.man:#x} {slave.id:#x} {slave.rev:#x} ({slave.name})",
    )
    # The same identity straight from the EEPROM words 0x08-0x0D.
    words = slave.eeprom_read(0x08) + slave.eeprom_read(0x0A) + slave.eeprom_read(0x0C)
    man, pid, rev = struct.unpack("<III", words[:12])
    check((man, pid, rev) == (vendor, product, 0x00010000), f"device {position} EEPROM identity")

drive = master.slaves[0]
check(struct.unpack("<I", drive.sdo_read(0x1018, 1))[0] == vendor, "SDO 0x1018:1 (expedited upload)")
check(struct.unpack("<I", drive.sdo_read(0x1000, 0))[0] == 0x00020192, "SDO 0x1000 device type")
name = drive.sdo_read(0x1008, 0).decode()
check(name == drive.name, f"SDO 0x1008 device name '{name}' (normal upload)")
label = "".join(chr(ord("A") + n % 26) for n in range(180))
drive.sdo_write(0x2000, 0, label.encode())
check(drive.sdo_read(0x2000, 0).decode() == label, "180-byte SDO 0x2000 (segmented download and upload)")
try:
    drive.sdo_read(0x5000, 0)
    check(False, "SDO 0x5000 should abort")
except pysoem.SdoError as error:
    check(error.abort_code == 0x06020000, f"abort code {error.abort_code:#010x} for a missing object")
try:
    drive.sdo_write(0x6041, 0, struct.pack("<H", 1))
    check(False, "SDO write of 0x6041 should abort")
except pysoem.SdoError as error:
    check(error.abort_code == 0x06010002, f"abort code {error.abort_code:#010x} for a read-only object")
for slave in master.slaves[:drives]:
    slave.sdo_write(0x6060, 0, struct.pack("<b", 8))
check(struct.unpack("<b", drive.sdo_read(0x6060, 0))[0] == 8, "mode of operation 8 (CSP) written and read back")

# Drive 0: the touch probe into its PDOs (SOEM reads the mapping back over CoE).
drive.sdo_write(0x1600, 0, bytes([0]))
drive.sdo_write(0x1600, 5, struct.pack("<I", 0x60B80010))
drive.sdo_write(0x1600, 0, bytes([5]))
drive.sdo_write(0x1A00, 0, bytes([0]))
drive.sdo_write(0x1A00, 6, struct.pack("<I", 0x60B90010))
drive.sdo_write(0x1A00, 7, struct.pack("<I", 0x60BA0020))
drive.sdo_write(0x1A00, 0, bytes([7]))

size = master.config_map()
check(size == drives * (12 + 16) + 2 + 2 + 6, f"IO map of {size} bytes")
check((len(drive.output), len(drive.input)) == (14, 22), "drive 0 PDOs 14 bytes out, 22 in")
for slave in master.slaves[1:drives]:
    check((len(slave.output), len(slave.input)) == (12, 16), "drive PDOs 12 bytes out, 16 in")
dio = master.slaves[drives]
check((len(dio.output), len(dio.input)) == (1, 1), "DIO PDOs 1 byte each way")

check(master.state_check(pysoem.SAFEOP_STATE, 500000) == pysoem.SAFEOP_STATE, "SAFE-OP")
master.state = pysoem.OP_STATE
master.write_state()
state = 0
for _ in range(200):
    master.send_processdata()
    master.receive_processdata(2000)
    state = master.state_check(pysoem.OP_STATE, 5000)
    if state == pysoem.OP_STATE:
        break
    time.sleep(0.001)
check(state == pysoem.OP_STATE, "OP")

expected = master.expected_wkc
check(expected == 3 * (drives + 1), f"expected working counter {expected}")
# Walk drive 0 to operation enabled, holding its position.
for cycle in range(300):
    status, position = struct.unpack_from("<Hi", drive.input, 0)
    state = status & 0x6F
    if state & 0x4F == 0x40:
        control = 0x06  # shutdown
    elif state == 0x21:
        control = 0x07  # switch on
    else:
        control = 0x0F  # enable operation
    drive.output = struct.pack("<HiiHH", control, position, 0, 0, 0)
    dio.output = bytes([0xA5])
    master.send_processdata()
    wkc = master.receive_processdata(2000)
    check(wkc == expected or cycle < 5, f"cycle {cycle}: working counter {wkc}") if wkc != expected else None
    if state == 0x27 and cycle > 20:
        break
    time.sleep(0.001)
status = struct.unpack_from("<H", drive.input, 0)[0]
check(status & 0x6F == 0x27, f"statusword {status:#06x}: operation enabled")

# Over the index at 0.3 mm (the drive stands at 0): 1 mm in steps of 262 increments (about
# 10 mm/s at 1 ms), touch probe 1 armed on the zero impulse.
target = struct.unpack_from("<i", drive.input, 2)[0]
probe = (0, 0)
for cycle in range(400):
    target = min(target + 262, 26214)
    drive.output = struct.pack("<HiiHH", 0x0F, target, 0, 0, 0x0015)
    master.send_processdata()
    master.receive_processdata(2000)
    probe = struct.unpack_from("<Hi", drive.input, 16)
    if probe[0] & 0x02 and cycle > 10:
        break
    time.sleep(0.001)
check(probe == (0x0043, 7864), f"touch probe status {probe[0]:#06x}, index latched at {probe[1]}")
master.state = pysoem.INIT_STATE
master.write_state()
master.close()
print("pysoem check passed")
