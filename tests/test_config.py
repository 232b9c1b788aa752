"""Robot config: defaults, the shipped example, and one clear message per mistake."""

from __future__ import annotations

import subprocess

import pytest

from hilnav.config import ConfigError, RobotConfig, default_toml_path, load_config, parse_config
from tests.conftest import HILNAV, hilnav_env


def test_the_shipped_example_equals_the_embedded_defaults():
    from_file = load_config(default_toml_path())
    assert from_file == RobotConfig(source=str(default_toml_path()))
    assert load_config(None).simulated


def test_a_partial_file_overrides_only_what_it_names(tmp_path):
    f = tmp_path / "r2.toml"
    f.write_text(
        'name = "r2"\nfleet = ["r1", "base"]\n[devices.arcos]\nport = "/dev/ttyUSB0"\n'
        "[services.mapping]\nresolution_m = 0.1\nassociation = false\n"
        '[zenoh]\nconnect = ["tcp/127.0.0.1:7447"]\nlisten = []\n'
        '[zenoh.usrpwd]\nuser = "r2"\npassword = "pw"\n'
    )
    cfg = load_config(f)
    assert cfg.name == "r2" and cfg.fleet == ("r1", "base")
    assert cfg.devices.arcos.port == "/dev/ttyUSB0" and cfg.devices.arcos.baud == 9600
    assert cfg.services.mapping.resolution_m == 0.1 and not cfg.services.mapping.association
    z = cfg.zenoh.settings()
    assert z.connect == ("tcp/127.0.0.1:7447",) and z.usrpwd == {"user": "r2", "password": "pw"}
    assert not z.multicast_scouting


@pytest.mark.parametrize(
    ("data", "words"),
    [
        ({"servces": {}}, ["servces", "did you mean services"]),
        (
            {"services": {"mapping": {"resolutoin_m": 0.1}}},
            ["did you mean services.mapping.resolution_m"],
        ),
        (
            {"services": {"mapping": {"resolution_m": -0.05}}},
            ["services.mapping.resolution_m", "-0.05", "> 0"],
        ),
        ({"devices": {"ir": {"link": "spi"}}}, ["devices.ir.link", "'spi'", "'serial', 'can'"]),
        ({"devices": {"gps": {"baud": "fast"}}}, ["devices.gps.baud", "'fast'", "baud = 9600"]),
        ({"geometry": {"ir_mounts": [[0.2, 0.0]]}}, ["geometry.ir_mounts[0]", "3 values"]),
        ({"zenoh": {"listen": ["127.0.0.1:7447"]}}, ["zenoh.listen[0]", "tcp/127.0.0.1:7447"]),
        ({"name": "r 1"}, ["name", "'r 1'", "letters"]),
        ({"devices": {"gyro": {"port": ""}}}, ["devices.gyro.port", '"sim"', "enabled = false"]),
        ({"services": {"heading": {"enabled": False}}}, ["services.mapping.enabled", "heading"]),
        ({"log": 3}, ["log = 3", "[log]"]),
    ],
)
def test_each_mistake_gets_one_message_naming_key_value_and_fix(data, words):
    with pytest.raises(ConfigError) as err:
        parse_config(data, "r1.toml")
    msg = str(err.value)
    assert msg.startswith("r1.toml: ") and "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_toml_syntax_errors_and_missing_files_are_clear(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('name = "r1\n')
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(f)
    with pytest.raises(ConfigError, match="no such config file"):
        load_config(tmp_path / "missing.toml")


def test_cli_config_check(tmp_path):
    good = subprocess.run(
        [*HILNAV, "config", "check", str(default_toml_path())],
        capture_output=True, text=True, env=hilnav_env(), timeout=60,
    )  # fmt: skip
    assert good.returncode == 0 and "ok" in good.stdout and "services:" in good.stdout
    f = tmp_path / "r1.toml"
    f.write_text("[services.maping]\nenabled = true\n")
    bad = subprocess.run(
        [*HILNAV, "config", "check", str(f)],
        capture_output=True, text=True, env=hilnav_env(), timeout=60,
    )  # fmt: skip
    assert bad.returncode == 2
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and "did you mean services.mapping" in lines[0], bad.stderr
