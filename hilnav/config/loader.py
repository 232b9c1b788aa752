"""Loading a robot's configuration: TOML checked key by key against the schema.

``load_config(None)`` gives the embedded defaults, a simulated Pioneer 3-DX with every
sensor in the office floor plan (``hilnav/config/default.toml`` spells the same defaults
out as an example). ``load_config(path)`` reads a TOML file whose tables override those
defaults. Anything wrong (TOML syntax, an unknown key, a wrong type, a value out of
range) raises :class:`ConfigError` with ONE message naming the key, the bad value and
the fix, with a did-you-mean for misspelt keys.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import tomllib
import typing
from pathlib import Path
from typing import Any

from hilnav.config.schema import ConfigError, RobotConfig
from msgs.typed import TypedReader, hints, join


def _type_word(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_type_word(args[0])}s"
        return f"a list of {len(args)} numbers" if args else "a list"
    if origin is dict or tp is dict:
        return "a table"
    return {float: "number", int: "integer", bool: "boolean (true/false)", str: "string"}.get(
        tp, str(tp)
    )


class _Loader(TypedReader):
    """The config's policy over msgs.typed: ConfigError naming the file, the key, the
    value and the fix; finite floats; unknown keys refused with a did-you-mean; each
    field's ``check`` metadata run; ``internal`` fields not settable from the file."""

    error = ConfigError

    def __init__(self, src: str) -> None:
        self.src = src

    def bad(self, path: str, value: Any, expect: str) -> ConfigError:
        return ConfigError(f"{self.src}: {path} = {value!r}: expected {expect}")

    def fail(self, kind: str, tp: Any, value: Any, path: str) -> ConfigError:
        if kind == "list":
            return self.bad(
                path, value, _type_word(tp) + f", e.g. {path.rsplit('.', 1)[-1]} = [...]"
            )
        if kind == "length":
            return self.bad(path, value, f"{len(typing.get_args(tp))} values, got {len(value)}")
        if kind == "mapping":
            return self.bad(path, value, "a table")
        if kind == "literal":
            return self.bad(path, value, "one of " + ", ".join(map(repr, typing.get_args(tp))))
        return self.bad(path, value, _type_word(tp))

    def scalar(self, tp: Any, value: Any, path: str) -> Any:
        if tp is float:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise self.bad(path, value, "a number")
            if not math.isfinite(value):
                raise self.bad(path, value, "a finite number")
            return float(value)
        if tp is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise self.bad(path, value, "an integer")
            return value
        if tp is bool:
            if not isinstance(value, bool):
                raise self.bad(path, value, "true or false")
            return value
        if tp is str:
            if not isinstance(value, str):
                raise self.bad(path, value, 'a string in quotes, e.g. "..."')
            return value
        raise self.bad(path, value, str(tp))  # pragma: no cover - a schema bug

    def record(self, cls: type, value: Any, path: str) -> Any:
        if not isinstance(value, dict):
            raise self.bad(path, value, f"a table, e.g. [{path}] on its own line")
        fields = {f.name: f for f in dataclasses.fields(cls) if not f.metadata.get("internal")}
        for k in value:
            if k not in fields:
                close = difflib.get_close_matches(k, list(fields), n=1, cutoff=0.6)
                hint = (
                    f"did you mean {join(path, close[0])}?"
                    if close
                    else f"known keys{' of [' + path + ']' if path else ''}: {', '.join(fields)}"
                )
                raise ConfigError(f"{self.src}: unknown key {join(path, k)!r}; {hint}")
        kwargs: dict[str, Any] = {}
        for name, f in fields.items():
            if name in value:
                kwargs[name] = self._field(f, hints(cls)[name], value[name], join(path, name))
        return cls(**kwargs)

    def _field(self, f: dataclasses.Field, tp: Any, value: Any, full: str) -> Any:
        """One field: read, with the default as the example of a fix, then checked."""
        if dataclasses.is_dataclass(tp):
            return self.record(tp, value, full)
        try:
            conv = self.read(tp, value, full)
        except ConfigError as exc:
            d = f.default
            if isinstance(d, bool | int | float | str) and "e.g." not in str(exc):
                toml = str(d).lower() if isinstance(d, bool) else repr(d).replace("'", '"')
                raise ConfigError(f"{exc}, e.g. {f.name} = {toml}") from None
            raise
        chk = f.metadata.get("check")
        if chk is not None:
            test, problem = chk
            try:
                ok = bool(test(conv))
            except (TypeError, ValueError, IndexError):
                ok = False
            if not ok:
                raise ConfigError(f"{self.src}: {full} = {value!r}: {problem}")
        return conv


def _build(cls: type, data: dict[str, Any], path: str, src: str) -> Any:
    """``cls`` from the TOML table ``data`` at ``path`` of the file ``src``."""
    return _Loader(src).record(cls, data, path)


def endpoint_problem(ep: str) -> str:
    """What is wrong with a Zenoh endpoint ``PROTO/ADDRESS:PORT`` ("" if nothing)."""
    proto, sep, rest = ep.partition("/")
    if not sep or not rest or proto not in ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream"):
        return 'expected PROTO/ADDRESS:PORT, e.g. "tcp/127.0.0.1:7447"'
    port = rest.rsplit(":", 1)[-1].split("#", 1)[0]
    if proto != "unixsock-stream" and (not port.isdigit() or int(port) > 65535):
        return "the port must be 0..65535"
    return ""


def _cross_checks(cfg: RobotConfig, src: str) -> None:
    d = cfg.devices
    for dev, dc in d.sections():
        can_ok = dev == "ir" and dc.link == "can" and (dc.can_channel or not dc.can_interface)
        if dc.enabled and not dc.port and not can_ok:
            raise ConfigError(
                f"{src}: devices.{dev}.port = '': give the port (e.g. /dev/ttyUSB0, "
                'tcp://127.0.0.1:8101) or "sim", or set devices.' + dev + ".enabled = false"
            )
    if cfg.services.mapping.enabled and not cfg.services.heading.enabled:
        raise ConfigError(
            f"{src}: services.mapping.enabled = true needs services.heading.enabled = true "
            "(the map is drawn with the fused heading); enable heading or disable mapping"
        )
    if cfg.zenoh.config_file and not Path(cfg.zenoh.config_file).is_file():
        raise ConfigError(
            f"{src}: zenoh.config_file = {cfg.zenoh.config_file!r}: no such file; give the "
            "path of a Zenoh JSON5 config or remove the key"
        )
    if cfg.zenoh.mode == "client" and not cfg.zenoh.connect and not cfg.zenoh.config_file:
        raise ConfigError(
            f"{src}: zenoh.mode = 'client' needs zenoh.connect: the routers to reach the "
            'fleet through, e.g. connect = ["tcp/127.0.0.1:7447"] (see hilnav router)'
        )
    eps = [(f"zenoh.listen[{i}]", e) for i, e in enumerate(cfg.zenoh.listen)]
    eps += [(f"zenoh.connect[{i}]", e) for i, e in enumerate(cfg.zenoh.connect)]
    for where, ep in eps:
        problem = endpoint_problem(ep)
        if problem:
            raise ConfigError(f"{src}: {where} = {ep!r}: {problem}")
    try:
        cfg.zenoh.settings().to_zenoh()
    except ValueError as exc:
        raise ConfigError(
            f"{src}: [zenoh] {exc}; see Zenoh's configuration reference for that key"
        ) from None


def parse_config(data: dict[str, Any], source: str = "<config>") -> RobotConfig:
    """A RobotConfig from already-parsed TOML data (defaults for what it leaves out)."""
    cfg = _build(RobotConfig, data, "", source)
    cfg = dataclasses.replace(cfg, source=source)
    _cross_checks(cfg, source)
    return cfg


def load_config(path: str | Path | None) -> RobotConfig:
    """The embedded defaults (None) or a TOML file over them; ConfigError if wrong."""
    if path is None:
        return RobotConfig()
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(
            f"{p}: no such config file; write one starting from {default_toml_path()} "
            "or run without --config for the simulated defaults"
        ) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(
            f"{p}: not valid TOML: {exc}; check quotes around strings and [table] headers"
        ) from None
    return parse_config(data, str(p))


def default_toml_path() -> Path:
    """The example config shipped with the package (same values as the defaults)."""
    return Path(__file__).with_name("default.toml")
