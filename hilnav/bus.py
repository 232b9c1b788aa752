"""The Zenoh bus of one robot: publish, subscribe, liveliness and queries, all as msgs.

Keys are ``hilnav/<robot>/<topic>``, payloads the JSON of
:func:`msgs.encode` with encoding ``application/json;hilnav.<Class>``; every sample a
:class:`Bus` publishes carries its own robot name as the Zenoh attachment (or that of the
robot it speaks for: ``hilnav play`` replays a log's robots), so receivers know who sent it.

A :class:`Bus` opens its Zenoh session from :class:`ZenohSettings`, or shares the
process's with other robots' buses (:class:`hilnav.bus_session.BusSession`: the robots of
a fleet host; subscriptions are the session's, each sample decoded once): peer mode (or
client mode, reaching the others through Zenoh routers: ``hilnav router``),
explicit ``listen``/``connect`` endpoints (``tcp/127.0.0.1:PORT``), multicast scouting OFF
unless switched on, optionally a native Zenoh JSON5 file as the base, plus Zenoh's own
access control, TLS and user/password sections passed through untouched. Those Zenoh
settings are the real protection; on top, a bus with a ``fleet`` list accepts samples only
from the robots it names (the key's robot and the sender must both be in the fleet):
anything else is counted as ``foreign`` and dropped, anything that does not decode (bad
JSON, wrong types, stamps outside 64 bits, NaN in a command, too large or too deeply
nested: :func:`msgs.decode`) is counted as ``malformed`` and dropped. Callbacks run on Zenoh's threads; an exception in
one is counted (``callback_errors``) and never reaches Zenoh.
"""

from __future__ import annotations

import json
import re
import socket
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import zenoh

import msgs
from hilnav.bus_session import BusSession, Payload
from hilnav.topics import EXPRESS, QUERIES, TOPICS, topic_type
from msgs import GroundTruth, PoseBox

PREFIX = "hilnav"

_BAD_NAME_CHARS = set("/*$?#@ ")


def check_name(name: str, what: str = "robot name") -> str:
    """A robot name must be one Zenoh key chunk: non-empty, no ``/ * $ ? # @`` or space."""
    if not name or any(c in _BAD_NAME_CHARS for c in name):
        raise ValueError(
            f"{what} {name!r}: use letters, digits, '-' or '_' (it becomes one Zenoh key "
            "chunk, hilnav/<robot>/...)"
        )
    return name


def zenoh_problem(exc: BaseException) -> str:
    """A Zenoh error as one readable line: the Rust source locations cut out, JSON5 parse
    errors reduced to their message, a busy listen port explained."""
    text = re.sub(r" at /[^ \]]+\.rs:\d+\.?", "", str(exc)).strip()
    m = re.search(r'msg: "((?:[^"\\]|\\.)*)"', text)
    if m:
        text = m.group(1).replace('\\"', '"')
    if "Unable to connect to any of" in text:
        text += (
            " (no router or robot answers there: start it first, e.g. `hilnav router`, or "
            "fix [zenoh] connect)"
        )
    if "Address already in use" in text:
        text += (
            " (another hilnav run, a router or another program listens there: stop it, or "
            "set [zenoh] listen to another port)"
        )
    return text


def key(robot: str, topic: str) -> str:
    return f"{PREFIX}/{robot}/{topic}"


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that is free right now (for tests and the demo)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass(frozen=True)
class ZenohSettings:
    """How to open the Zenoh session (the ``[zenoh]`` table of a robot config).

    ``config_file`` is a native Zenoh JSON5 config used as the base; the fields below are
    then applied on top (``mode``, ``listen``, ``connect`` only when set; scouting always).
    ``mode`` is Zenoh's: ``peer`` (the default), ``client`` (talks only to the routers or
    peers it connects to, and listens nowhere: ``listen`` is not used) or ``router``.
    ``access_control``, ``tls`` and ``usrpwd`` are Zenoh's own sections
    (``access_control``, ``transport/link/tls``, ``transport/auth/usrpwd``), passed through
    as given; ``extra`` maps any other Zenoh config path to its value.
    """

    mode: str = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    multicast_scouting: bool = False
    gossip_scouting: bool = False
    config_file: str | None = None
    access_control: dict[str, Any] | None = None
    tls: dict[str, Any] | None = None
    usrpwd: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def loopback(
        cls, listen_port: int | None = None, connect_ports: Iterable[int] = ()
    ) -> ZenohSettings:
        """Peer on 127.0.0.1: listen on one port, connect to others (tests, the demo)."""
        listen = (f"tcp/127.0.0.1:{listen_port}",) if listen_port else ()
        return cls(listen=listen, connect=tuple(f"tcp/127.0.0.1:{p}" for p in connect_ports))

    def to_zenoh(self) -> zenoh.Config:
        """The zenoh.Config these settings describe; ValueError naming the Zenoh config
        path whose value Zenoh refuses."""
        try:
            conf = zenoh.Config.from_file(self.config_file) if self.config_file else zenoh.Config()
        except zenoh.ZError as exc:
            raise ValueError(f"{self.config_file}: {zenoh_problem(exc)}") from None

        def put(path: str, value: Any) -> None:
            try:
                conf.insert_json5(path, json.dumps(value))
            except zenoh.ZError as exc:
                raise ValueError(f"{path} = {value!r}: {zenoh_problem(exc)}") from None

        if self.mode and (not self.config_file or self.mode != "peer"):
            put("mode", self.mode)
        if self.mode == "client":
            put("listen/endpoints", [])  # a client reaches others through its routers only
        elif self.listen or not self.config_file:
            # no listen given: listen nowhere (Zenoh's default would be every interface)
            put("listen/endpoints", list(self.listen))
        if self.connect:
            put("connect/endpoints", list(self.connect))
        put("scouting/multicast/enabled", self.multicast_scouting)
        put("scouting/gossip/enabled", self.gossip_scouting)
        if self.access_control is not None:
            put("access_control", self.access_control)
        if self.tls is not None:
            put("transport/link/tls", self.tls)
        if self.usrpwd is not None:
            put("transport/auth/usrpwd", self.usrpwd)
        for path, value in self.extra.items():
            put(path, value)
        return conf


@dataclass
class BusStats:
    """Counters of one bus (read them from any thread; they only grow)."""

    published: int = 0
    received: int = 0
    malformed: int = 0
    foreign: int = 0
    callback_errors: int = 0
    queries_answered: int = 0
    last_problem: str = ""


Callback = Callable[[str, Any], None]


class Bus:
    """One robot's view of the Zenoh bus (see the module docstring)."""

    def __init__(
        self,
        robot: str,
        zenoh_cfg: ZenohSettings | zenoh.Config | None = None,
        fleet: Iterable[str] | None = None,
        *,
        shared: BusSession | None = None,
    ) -> None:
        """``shared``: the process's session, which other robots' buses use too (then
        ``zenoh_cfg`` is not used; its owner closes it); else a session of its own."""
        self.robot = check_name(robot)
        self.fleet: frozenset[str] | None = None
        if fleet is not None:
            self.fleet = frozenset(check_name(r, "fleet member") for r in fleet) | {robot}
        self.stats = BusStats()
        self._lock = threading.Lock()
        self._own = shared is None
        self.zsession = shared or BusSession(
            zenoh_cfg if zenoh_cfg is not None else ZenohSettings()
        )
        self.session = self.zsession.session
        self._attachment = robot.encode()
        self._publishers: dict[tuple[str, str], Any] = {}
        self._declared: list[Any] = []
        self._token: Any = None
        self._closed = False

    # -- helpers -----------------------------------------------------------------------
    def _count(self, what: str, problem: str) -> None:
        with self._lock:
            setattr(self.stats, what, getattr(self.stats, what) + 1)
            self.stats.last_problem = problem

    def allowed(self, robot: str) -> bool:
        return self.fleet is None or robot in self.fleet

    # -- publishing ----------------------------------------------------------------------
    def publish(self, topic: str, msg: Any) -> None:
        """Put ``msg`` on ``hilnav/<own robot>/<topic>``."""
        self.publish_to(self.robot, topic, msg)

    def publish_to(self, robot: str, topic: str, msg: Any, sender: str | None = None) -> None:
        """Put ``msg`` on another robot's key (e.g. its ``cmd_vel``); sender = this bus,
        unless ``sender`` names another (``hilnav play`` speaks for the robots of a log)."""
        self.put_encoded(robot, topic, msgs.encode(msg), msgs.schema_name(type(msg)), sender)

    def put_encoded(
        self, robot: str, topic: str, data: bytes, schema_name: str, sender: str | None = None
    ) -> None:
        """Put an already encoded JSON payload on ``hilnav/<robot>/<topic>``."""
        pub = self._publishers.get((robot, topic))
        if pub is None:
            pub = self._publisher(robot, topic, schema_name)
        pub.put(data, attachment=self._attachment if sender is None else sender.encode())
        with self._lock:
            self.stats.published += 1

    def _publisher(self, robot: str, topic: str, schema_name: str) -> Any:
        """The publisher of ``hilnav/<robot>/<topic>``, declared once (express for the
        topics of :data:`hilnav.topics.EXPRESS`: sent at once, not batched)."""
        with self._lock:
            pub = self._publishers.get((robot, topic))
            if pub is None:
                enc = zenoh.Encoding.APPLICATION_JSON.with_schema(schema_name)
                pub = self.session.declare_publisher(
                    key(robot, topic), encoding=enc, express=topic in EXPRESS
                )
                self._publishers[(robot, topic)] = pub
            return pub

    # -- subscribing ---------------------------------------------------------------------
    def subscribe(self, robot: str, topic: str, callback: Callback) -> Any:
        """Call ``callback(robot, msg)`` for each valid ``msg`` on ``hilnav/<robot>/<topic>``.

        ``robot`` may be ``*`` (every robot). ``topic`` must be a hilnav topic (its class
        decodes the payload). Samples from outside the fleet, or that do not decode, are
        counted in :attr:`stats` and dropped.
        """
        if topic_type(topic) is None:
            raise ValueError(f"topic {topic!r}: not a hilnav topic; known: {sorted(TOPICS)}")
        if robot != "*":
            check_name(robot)
        return self._declare_subscriber(key(robot, topic), lambda r, t, m: callback(r, m))

    def subscribe_all(self, callback: Callable[[str, str, Any], None]) -> Any:
        """Call ``callback(robot, topic, msg)`` for every valid message of every robot
        (``hilnav/*/**``), checked as :meth:`subscribe` does; keys that are no hilnav topic
        (views played by ``hilnav play --topics``, say) are ignored."""
        return self._declare_subscriber(key("*", "**"), callback)

    def _declare_subscriber(self, keyexpr: str, callback: Callable[[str, str, Any], None]) -> Any:
        sub = self.zsession.subscribe(keyexpr, self, callback)
        self._declared.append(sub)
        return sub

    def deliver(
        self, sample: zenoh.Sample, payload: Payload, callback: Callable[[str, str, Any], None]
    ) -> None:
        """``callback(robot, topic, msg)`` if the sample is a valid message of the fleet
        (counted in :attr:`stats` either way); ``payload`` decodes it at most once for
        every bus of the session."""
        try:
            head = payload.head()
            if head is None:
                return
            src, topic, sender = head
            if not src or not self.allowed(src) or not sender or not self.allowed(sender):
                self._count("foreign", f"{sample.key_expr} from {sender or '?'}: not in fleet")
                return
            msg = payload.msg()
        except msgs.DecodeError as exc:
            self._count("malformed", f"{sample.key_expr}: {exc}")
            return
        except Exception as exc:
            self._count("malformed", f"{sample.key_expr}: {exc!r}")
            return
        claimed = getattr(msg, "robot", None)
        if isinstance(msg, PoseBox | GroundTruth) and claimed != src:
            self._count("foreign", f"{sample.key_expr}: message claims robot {claimed!r}")
            return
        with self._lock:
            self.stats.received += 1
        try:
            callback(src, topic, msg)
        except Exception as exc:
            self._count("callback_errors", f"{sample.key_expr}: callback: {exc!r}")

    # -- liveliness ----------------------------------------------------------------------
    def declare_alive(self) -> None:
        """Declare the liveliness token ``hilnav/<robot>/alive`` (until :meth:`close`)."""
        if self._token is None:
            self._token = self.session.liveliness().declare_token(key(self.robot, "alive"))

    def on_liveliness(self, callback: Callable[[str, bool], None]) -> Any:
        """``callback(robot, alive)`` for fleet robots appearing (also those already alive)
        and disappearing."""
        sub = self.zsession.on_liveliness(self, callback)
        self._declared.append(sub)
        return sub

    def liveliness(self, keyexpr: str, alive: bool, callback: Callable[[str, bool], None]) -> None:
        """A token of ``keyexpr`` appeared or went: ``callback`` if it is a fleet robot's."""
        parts = keyexpr.split("/")
        if len(parts) != 3 or parts[2] != "alive":
            self._count("malformed", f"{keyexpr}: not a liveliness key")
            return
        if not self.allowed(parts[1]):
            self._count("foreign", f"{keyexpr}: not in fleet")
            return
        try:
            callback(parts[1], alive)
        except Exception as exc:
            self._count("callback_errors", f"{keyexpr}: callback: {exc!r}")

    # -- queries ------------------------------------------------------------------------
    def queryable(self, name: str, handler: Callable[[], Any]) -> Any:
        """Answer ``hilnav/<robot>/query/<name>`` with ``handler()`` (no reply if None)."""
        k = key(self.robot, f"query/{name}")

        def on_query(query: zenoh.Query) -> None:
            try:
                msg = handler()
            except Exception as exc:
                self._count("callback_errors", f"{k}: handler: {exc!r}")
                query.reply_err(f"handler failed: {exc}".encode())
                return
            if msg is None:
                query.reply_err(b"nothing yet")
                return
            enc = zenoh.Encoding.APPLICATION_JSON.with_schema(msgs.schema_name(type(msg)))
            query.reply(k, msgs.encode(msg), encoding=enc, attachment=self._attachment)
            with self._lock:
                self.stats.queries_answered += 1

        q = self.session.declare_queryable(k, on_query)
        self._declared.append(q)
        return q

    def query(self, robot: str, name: str, timeout_s: float = 2.0, cls: type | None = None) -> Any:
        """Ask ``hilnav/<robot>/query/<name>``; the decoded answer, or None (no answer,
        an error reply, or a malformed one, which is counted)."""
        cls = cls or QUERIES.get(name)
        if cls is None:
            raise ValueError(f"query {name!r}: unknown; give cls= or one of {sorted(QUERIES)}")
        replies = self.session.get(key(check_name(robot), f"query/{name}"), timeout=timeout_s)
        for reply in replies:  # bounded: the handler ends at the timeout
            ok = reply.ok
            if ok is None:
                continue
            try:
                return msgs.decode(cls, ok.payload.to_bytes())
            except msgs.DecodeError as exc:
                self._count("malformed", f"query {name} from {robot}: {exc}")
        return None

    # -- shutdown -----------------------------------------------------------------------
    def close(self) -> None:
        """Undeclare the token, subscribers, queryables and publishers; close the session."""
        if self._closed:
            return
        self._closed = True
        for ent in [self._token, *self._declared, *self._publishers.values()]:
            if ent is None:
                continue
            try:
                ent.undeclare()
            except zenoh.ZError:
                pass
        self._token = None
        self._declared.clear()
        self._publishers.clear()
        if self._own:  # a shared session is closed by its owner
            self.zsession.close()

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
