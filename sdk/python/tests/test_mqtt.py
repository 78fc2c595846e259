"""The MQTT publisher of `rtcnc serve` against a real broker (Debian's mosquitto, with user
names and passwords, started here) and an independent subscriber (paho-mqtt): the retained
state, positions that change while the machine moves, an e-stop as an alarm, and no alarm
lost while the broker is stopped and started again."""

from __future__ import annotations

import getpass
import json
import shutil
import socket
import subprocess
import threading
import time
from pathlib import Path

import paho.mqtt.client as mqtt
import pytest

from conftest import Server, machine_file, wait_state

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
PREFIX = "factory/mill-1"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Broker:
    """mosquitto on a free port, users `rtcnc` and `reader`, its sessions persisted across
    a restart (as a production broker keeps them)."""

    def __init__(self, folder: Path, tls: bool = False):
        self.folder = folder
        self.port = free_port()
        passwords = folder / "passwd"
        passwords.write_text("")
        for user, password in (("rtcnc", "publisher-password"), ("reader", "reader-password")):
            subprocess.run(["mosquitto_passwd", "-b", str(passwords), user, password], check=True)
        self.config = folder / "mosquitto.conf"
        # As root, mosquitto drops to the user named here (else `mosquitto`, who cannot read
        # pytest's folders); as anyone else it ignores the line.
        self.config.write_text(
            f"user {getpass.getuser()}\nlistener {self.port} 127.0.0.1\nallow_anonymous false\npassword_file {passwords}\n"
            f"persistence true\npersistence_location {folder}/\nautosave_interval 1\n"
            + (f"cafile {folder}/ca.pem\ncertfile {folder}/server.pem\nkeyfile {folder}/server.key\n" if tls else ""))
        self.process: subprocess.Popen | None = None
        self.start()

    def start(self) -> None:
        self.process = subprocess.Popen([MOSQUITTO, "-c", str(self.config)],
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        end = time.monotonic() + 10
        while time.monotonic() < end:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return
            except OSError:
                time.sleep(0.05)
        raise TimeoutError("mosquitto did not listen")

    def stop(self) -> None:
        if self.process:
            self.process.terminate()
            self.process.wait(10)
            self.process = None


def make_certificates(folder: Path) -> None:
    """A CA and the broker's certificate for localhost, made with openssl."""
    def run(*args: str) -> None:
        subprocess.run(["openssl", *args], cwd=folder, check=True, capture_output=True)
    run("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out", "ca.pem", "-days", "2",
        "-subj", "/CN=rtcnc test CA")
    run("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "server.key", "-out", "server.csr", "-subj", "/CN=localhost")
    (folder / "san.ext").write_text("subjectAltName=DNS:localhost,IP:127.0.0.1\n")
    run("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial",
        "-out", "server.pem", "-days", "2", "-extfile", "san.ext")


class Subscriber:
    """paho, persistent session, QoS 1, reconnecting by itself."""

    def __init__(self, port: int, ca: Path | None = None):
        self.messages: list[tuple[str, dict, bool]] = []
        self.lock = threading.Lock()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="pytest-reader", clean_session=False)
        self.client.username_pw_set("reader", "reader-password")
        self.client.reconnect_delay_set(0.2, 1)
        self.client.on_connect = lambda c, u, f, rc, p: c.subscribe(f"{PREFIX}/#", qos=1)
        self.client.on_message = self._on_message
        if ca is not None:
            self.client.tls_set(ca_certs=str(ca))
        self.client.connect("localhost" if ca is not None else "127.0.0.1", port, keepalive=5)
        self.client.loop_start()

    def _on_message(self, client, userdata, msg):
        try:
            payload = json.loads(msg.payload)
        except ValueError:
            payload = msg.payload.decode()
        with self.lock:
            self.messages.append((msg.topic, payload, bool(msg.retain)))

    def on(self, topic: str) -> list:
        with self.lock:
            return [p for t, p, _ in self.messages if t == f"{PREFIX}/{topic}"]

    def wait(self, predicate, timeout: float = 20.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return
            time.sleep(0.05)
        raise TimeoutError(self.messages[-10:])

    def close(self):
        self.client.loop_stop()
        self.client.disconnect()


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mqtt")
    broker = Broker(folder)
    subscriber = Subscriber(broker.port)
    (folder / "mqtt-password").write_text("publisher-password\n")
    config = machine_file(folder)
    config.write_text(config.read_text() + (
        f'\n[mqtt]\nenabled = true\nhost = "127.0.0.1"\nport = {broker.port}\ntopic_prefix = "{PREFIX}"\n'
        'username = "rtcnc"\npassword_file = "mqtt-password"\nrate_hz = 20\nkeep_alive_s = 1\n'))
    server = Server(folder, config=config)
    yield broker, subscriber, server
    subscriber.close()
    server.stop()
    broker.stop()


def operator(server: Server):
    """One operator for the module, holding the lease, the machine idle."""
    c = getattr(server, "operator", None)
    if c is None:
        c = server.operator = server.client("operator")
        c.acquire_lease(take_over=False)
    if c.status().state != "idle":
        c.reset().wait(10)
    wait_state(c, lambda s: s.state == "idle")
    return c


def test_state_is_retained_and_positions_follow_the_machine(setup):
    broker, subscriber, server = setup
    subscriber.wait(lambda: subscriber.on("state") and subscriber.on("online"))
    assert subscriber.on("online")[-1] is True
    # A second subscriber that comes later still gets the state: it is retained.
    late = Subscriber.__new__(Subscriber)
    late.messages, late.lock = [], threading.Lock()
    late.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="pytest-late")
    late.client.username_pw_set("reader", "reader-password")
    late.client.on_connect = lambda c, u, f, rc, p: c.subscribe(f"{PREFIX}/state", qos=1)
    late.client.on_message = late._on_message
    late.client.connect("127.0.0.1", broker.port)
    late.client.loop_start()
    late.wait(lambda: late.on("state"))
    assert late.messages[0][2], "delivered as a retained message"
    late.close()

    op = operator(server)
    subscriber.wait(lambda: subscriber.on("state")[-1]["state"] == "idle")
    start = len(subscriber.on("position"))
    op.mdi("G0 X40").wait(30)
    s = op.status()
    subscriber.wait(lambda: any(p["machine"]["X"] == pytest.approx(s.machine_position["X"], abs=1e-9)
                                for p in subscriber.on("position")[start:]))
    xs = [p["machine"]["X"] for p in subscriber.on("position")[start:]]
    assert len(set(xs)) >= 3, "positions came while X moved"
    assert subscriber.on("overrides")[-1] == {"feed": 1.0, "rapid": 1.0, "spindle": 1.0}


def test_an_estop_is_an_alarm(setup):
    broker, subscriber, server = setup
    op = operator(server)
    op.estop()
    wait_state(op, lambda s: s.state == "estop")
    fault = [f for f in op.faults() if f.code == "kernel.estop"][-1]
    subscriber.wait(lambda: any(a["seq"] == fault.seq for a in subscriber.on("alarm")))
    alarm = [a for a in subscriber.on("alarm") if a["seq"] == fault.seq][0]
    assert alarm["code"] == "kernel.estop" and alarm["message"] == fault.message
    subscriber.wait(lambda: subscriber.on("state")[-1]["state"] == "estop")
    op.reset().wait(10)


def test_no_alarm_is_lost_while_the_broker_is_away(setup):
    broker, subscriber, server = setup
    op = operator(server)
    broker.stop()
    time.sleep(1.5)
    for _ in range(3):
        op.estop()
        wait_state(op, lambda s: s.state == "estop")
        op.reset().wait(10)
        wait_state(op, lambda s: s.state == "idle")
    while_away = [f.seq for f in op.faults() if f.code == "kernel.estop"][-3:]
    time.sleep(1.0)
    broker.start()
    subscriber.wait(lambda: set(while_away) <= {a["seq"] for a in subscriber.on("alarm")}, 30)
    seqs = [a["seq"] for a in subscriber.on("alarm")]
    # At least once (QoS 1): a repeat is allowed, a loss or a change of order is not.
    assert list(dict.fromkeys(q for q in seqs if q in while_away)) == while_away


def test_tls_to_the_broker(tmp_path):
    make_certificates(tmp_path)
    broker = Broker(tmp_path, tls=True)
    subscriber = Subscriber(broker.port, ca=tmp_path / "ca.pem")
    (tmp_path / "mqtt-password").write_text("publisher-password\n")
    config = machine_file(tmp_path)
    config.write_text(config.read_text() + (
        f'\n[mqtt]\nenabled = true\nhost = "localhost"\nport = {broker.port}\ntopic_prefix = "{PREFIX}"\n'
        'username = "rtcnc"\npassword_file = "mqtt-password"\ntls = true\nca_certificate = "ca.pem"\n'))
    server = Server(tmp_path, config=config)
    try:
        subscriber.wait(lambda: subscriber.on("state") and subscriber.on("online"))
        assert subscriber.on("online")[-1] is True
        subscriber.wait(lambda: len(subscriber.on("position")) >= 3)
    finally:
        subscriber.close()
        server.stop()
        broker.stop()
