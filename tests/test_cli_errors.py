"""Every command a user can point at a wrong file, port or config answers with one line
naming what is wrong (exit 2), never a traceback, and never a silent exit 0."""

from __future__ import annotations

import subprocess

import pytest

from tests.conftest import HILNAV, hilnav_env


def _run(*args: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([*HILNAV, *args], capture_output=True, text=True, cwd=cwd,
                          env=hilnav_env(), timeout=60)  # fmt: skip


@pytest.fixture
def files(tmp_path):
    (tmp_path / "text.mcap").write_text("hello\n")
    (tmp_path / "zeros.bin").write_bytes(bytes(3000))
    (tmp_path / "zenoh.toml").write_text('[zenoh.access_control]\nenabled = "yes"\n')
    (tmp_path / "port.toml").write_text('[zenoh]\nlisten = ["tcp/127.0.0.1:99999"]\n')
    (tmp_path / "baud.toml").write_text("[devices.arcos]\nbaud = 9223372036854775807\n")
    return tmp_path


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("log", "info", "text.mcap"), "not an MCAP file"),
        (("log", "recover", "text.mcap", "out.mcap"), "not an MCAP file"),
        (("analyze", "text.mcap"), "text.mcap: not an MCAP file"),
        (("analyze", "text.mcap", "--out", "zeros.bin"), "--out zeros.bin: a file of that name"),
        (("replay", "text.mcap", "--out", "o.mcap"), "not an MCAP file"),
        (("probe", "arcos", "zeros.bin"), "no arcos messages in this file"),
        (("probe", "gps", "text.mcap"), "no gps messages in this file"),
        (("config", "check", "zenoh.toml"), "access_control = {'enabled': 'yes'}: invalid type"),
        (("config", "check", "port.toml"), "the port must be 0..65535"),
        (("config", "check", "baud.toml"), "devices.arcos.baud = 9223372036854775807"),
    ],
)
def test_a_wrong_input_gets_one_clear_line(files, args, says):
    r = _run(*args, cwd=files)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "Traceback" not in r.stderr and says in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert ".rs:" not in r.stderr  # no Rust source paths from Zenoh


def test_an_unwritable_output_is_named(files):
    good = files / "good.mcap"
    from hilnav.log.writer import LogWriter
    from msgs import GyroSample

    with LogWriter(good) as w:
        w.write("/r1/gyro", GyroSample(1, 0.0, 0.0), 1)
    r = _run("log", "recover", "good.mcap", "no/such/dir/out.mcap", cwd=files)
    assert r.returncode == 2 and "no/such/dir/out.mcap: No such file or directory" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_second_daemon_on_a_busy_zenoh_port_is_told_why():
    import zenoh

    from hilnav.bus import ZenohSettings, free_tcp_port
    from hilnav.config import parse_config
    from hilnav.daemon import Daemon, DaemonError

    port = free_tcp_port()
    first = zenoh.open(ZenohSettings.loopback(port).to_zenoh())
    try:
        cfg = parse_config({"zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]}}, "<test>")
        with pytest.raises(DaemonError, match="another hilnav run") as err:
            Daemon(cfg).start()
        assert ".rs:" not in str(err.value) and "Address already in use" in str(err.value)
    finally:
        first.close()
