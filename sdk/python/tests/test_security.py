"""The API server alone (`rtcnc api`, no machine): loopback by default, TLS or
--insecure-http elsewhere, TLS with a certificate, the first admin's one-time password,
the log-in rate limit, the body limit. Without a machine every machine endpoint answers 503."""

from __future__ import annotations

import json
import re
import ssl
import subprocess
import time
from pathlib import Path

import httpx
import pytest

import rtcnc
from conftest import BIN, machine_file


def start_api(folder: Path, *extra: str) -> tuple[subprocess.Popen, str, str]:
    config = machine_file(folder)
    p = subprocess.Popen([str(BIN), "api", "--machine", str(config), "--segment", f"rtcnc-pytest-none-{folder.name}",
                          "--users", str(folder / "users.toml"), "--programs", str(folder / "programs"), *extra],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url, password = "", ""
    end = time.monotonic() + 30
    assert p.stdout is not None
    while not url and time.monotonic() < end:
        line = p.stdout.readline()
        if m := re.search(r"listening on (\S+)", line):
            url = m.group(1)
        if not line and p.poll() is not None:
            break
    return p, url, password


def stop(p: subprocess.Popen) -> str:
    p.terminate()
    try:
        _, err = p.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        p.kill()
        _, err = p.communicate()
    return err


def test_another_address_needs_tls_or_insecure_http(tmp_path):
    config = machine_file(tmp_path)
    r = subprocess.run([str(BIN), "api", "--machine", str(config), "--listen", "0.0.0.0:0",
                        "--users", str(tmp_path / "users.toml"), "--programs", str(tmp_path / "p")],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode != 0 and "not a loopback address" in r.stderr


def test_the_first_start_prints_a_one_time_admin_password_once(tmp_path):
    p, url, _ = start_api(tmp_path, "--listen", "127.0.0.1:0")
    # The password is on standard error: read it after the stop.
    assert url
    err = stop(p)
    m = re.search(r"one-time password is: (\S+)", err)
    assert m, err
    password = m.group(1)
    assert "admin" in (tmp_path / "users.toml").read_text() and password not in (tmp_path / "users.toml").read_text()
    # A second start: the file exists, no password is printed.
    p, url, _ = start_api(tmp_path, "--listen", "127.0.0.1:0")
    try:
        c = rtcnc.Client(url)
        info = c.login("admin", password)
        assert info.password_change_required
        with pytest.raises(rtcnc.Forbidden) as e:
            c.acquire_lease()
        assert e.value.code == "auth.password_change_required"
        c.change_password(password, "a-new-password")
        c.acquire_lease()
        # No machine behind this API: 503 with a problem document.
        with pytest.raises(rtcnc.MachineUnavailable) as e:
            c.status()
        assert e.value.code == "machine.unavailable"
        # Bodies over the limit are refused with a problem document.
        r = httpx.post(f"{url}/api/control/mdi", headers={"Authorization": f"Bearer {c.token}",
                       "content-type": "application/json"}, content=b'{"line":"' + b"x" * 100_000 + b'"}')
        assert r.status_code == 413 and r.headers["content-type"].startswith("application/problem+json")
        # Five failed log-ins a minute from one address, then 429.
        bad = rtcnc.Client(url)
        for _ in range(5):
            with pytest.raises(rtcnc.Unauthorized):
                bad.login("admin", "wrong-password")
        with pytest.raises(rtcnc.RateLimited) as e:
            bad.login("admin", "a-new-password")
        assert e.value.status == 429
    finally:
        err = stop(p)
    assert "one-time password" not in err
    assert "a-new-password" not in err and password not in err


def test_tls_with_a_certificate(tmp_path):
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256",
                    "-nodes", "-keyout", str(tmp_path / "key.pem"), "-out", str(tmp_path / "cert.pem"),
                    "-days", "1", "-subj", "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1"],
                   check=True, capture_output=True)
    p, url, _ = start_api(tmp_path, "--listen", "127.0.0.1:0", "--tls-cert", str(tmp_path / "cert.pem"),
                          "--tls-key", str(tmp_path / "key.pem"))
    try:
        assert url.startswith("https://")
        trust = ssl.create_default_context(cafile=str(tmp_path / "cert.pem"))
        r = httpx.get(f"{url}/api/openapi.json", verify=trust)
        assert r.status_code == 200 and r.json()["openapi"] == "3.1.0"
        with pytest.raises(httpx.HTTPError):
            httpx.get(url.replace("https://", "http://") + "/api/openapi.json", timeout=5)
    finally:
        stop(p)


def test_sessions_expire_and_websocket_messages_are_limited(tmp_path):
    import asyncio

    import websockets

    from conftest import add_users, PASSWORDS

    add_users(tmp_path / "users.toml")
    p, url, _ = start_api(tmp_path, "--listen", "127.0.0.1:0", "--session-seconds", "2")
    try:
        c = rtcnc.Client(url)
        c.login("viewer", PASSWORDS["viewer"][1])
        assert c.session().user == "viewer"

        async def oversize() -> bool:
            ws_url = url.replace("http://", "ws://") + f"/api/ws?token={c.token}"
            async with websockets.connect(ws_url) as ws:
                first = json.loads(await ws.recv())
                assert first["type"] == "snapshot"
                await ws.send("x" * 10_000)
                try:
                    while True:
                        await asyncio.wait_for(ws.recv(), 5)
                except websockets.ConnectionClosed:
                    return True
            return False

        assert asyncio.run(oversize()), "a message over 4 KiB closes the socket"
        time.sleep(3)  # longer than the session's 2 s
        with pytest.raises(rtcnc.Unauthorized) as e:
            c.session()
        assert e.value.code == "auth.expired"
    finally:
        stop(p)
