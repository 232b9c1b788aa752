"""One robot's configuration: a TOML file checked key by key against typed dataclasses.

- :mod:`hilnav.config.schema`: the tables and their checks (:class:`RobotConfig`);
- :mod:`hilnav.config.loader`: :func:`load_config`, :func:`parse_config` and the one-line
  :class:`ConfigError` naming key, value and fix;
- :mod:`hilnav.config.views`: the config as plain data, a summary, the IR board settings;
- :mod:`hilnav.config.reference`: the Markdown reference (docs/configuration.md).
"""

from hilnav.config.loader import default_toml_path, load_config, parse_config
from hilnav.config.schema import (
    DEG,
    ArcosDevice,
    CmdVel,
    ConfigError,
    Devices,
    Geometry,
    GpsDevice,
    GyroDevice,
    HeadingService,
    IrDevice,
    LocalizationService,
    Log,
    MappingService,
    Noise,
    PoseService,
    RobotConfig,
    Services,
    Simulation,
    ZenohTable,
)
from hilnav.config.views import config_data, ir_board_config, summary

__all__ = [
    "DEG",
    "ArcosDevice",
    "CmdVel",
    "ConfigError",
    "Devices",
    "Geometry",
    "GpsDevice",
    "GyroDevice",
    "HeadingService",
    "IrDevice",
    "LocalizationService",
    "Log",
    "MappingService",
    "Noise",
    "PoseService",
    "RobotConfig",
    "Services",
    "Simulation",
    "ZenohTable",
    "config_data",
    "default_toml_path",
    "ir_board_config",
    "load_config",
    "parse_config",
    "summary",
]
