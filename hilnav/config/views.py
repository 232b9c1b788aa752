"""What other parts read off a robot's configuration: its plain data (what the daemon
hands ``hilnav fake``), a summary for ``hilnav config check``, the IR board settings."""

from __future__ import annotations

import dataclasses
from typing import Any

from drivers.irboard import IrBoardConfig
from hilnav.config.schema import RobotConfig


def config_data(cfg: RobotConfig) -> dict[str, Any]:
    """The config as plain TOML/JSON-able data: ``parse_config(config_data(c))`` gives
    back ``c`` (this is how the daemon hands its resolved config to ``hilnav fake``)."""

    def plain(v: Any) -> Any:
        if isinstance(v, tuple | list):
            return [plain(x) for x in v]
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        return v

    data = plain(dataclasses.asdict(cfg))
    data.pop("source", None)
    return data


def summary(cfg: RobotConfig) -> str:
    """A few lines saying what the config will run (for ``hilnav config check``)."""
    d = cfg.devices
    lines = [f"robot {cfg.name} (config {cfg.source})"]
    for name, dc in d.sections():
        if not dc.enabled:
            lines.append(f"  {name:6s} off")
            continue
        where = f"{dc.port} @ {dc.baud} baud"
        if name == "ir" and dc.link == "can":
            where = f"CAN {dc.can_interface}:{dc.can_channel or dc.port} @ {dc.can_bitrate} bit/s"
        lines.append(f"  {name:6s} {where}")
    sv = cfg.services
    on = [n for n in ("heading", "pose", "mapping", "localization") if getattr(sv, n).enabled]
    lines.append(f"  services: {', '.join(on) or 'none'}")
    z = cfg.zenoh
    lines.append(
        f"  zenoh {z.mode}: listen {list(z.listen)} connect {list(z.connect)} "
        f"multicast scouting {'on' if z.multicast_scouting else 'off'}"
    )
    lines.append(f"  fleet: {', '.join(cfg.fleet) or '(only itself)'}")
    lines.append(f"  log: {cfg.log.dir if cfg.log.enabled else 'off'}")
    return "\n".join(lines)


def ir_board_config(cfg: RobotConfig) -> IrBoardConfig:
    """The IR ADC board settings of a robot config, as the IR driver and codecs take them."""
    ir = cfg.devices.ir
    return IrBoardConfig(
        board_id=ir.board_id,
        adc_bits=ir.adc_bits,
        vref_v=ir.vref_v,
        rate_hz=ir.rate_hz,
        mounts=cfg.geometry.ir_mounts_rad(),
        median_window=ir.median_window,
    )
