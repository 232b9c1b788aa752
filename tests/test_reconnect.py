"""The reconnect policy every driver uses (drivers.reconnect.Reconnect)."""

from drivers.reconnect import POLL_S, Reconnect, local_path


def test_backoff_doubles_to_its_cap_and_resets_on_success():
    rc = Reconnect(initial_s=0.25, max_s=1.0)
    rc.lost(10.0)
    assert not rc.due(10.2) and rc.due(10.25)
    for expect in (0.5, 1.0, 1.0):
        rc.failed(20.0)
        assert rc.backoff_s == expect and rc.retry_at == 20.0 + expect
    rc.succeeded()
    assert rc.backoff_s == 0.25


def test_a_watched_port_is_tried_the_moment_it_comes_back(tmp_path):
    port = tmp_path / "ttyUSB0"
    rc = Reconnect(initial_s=0.25, max_s=1.0, path=str(port))
    for _ in range(4):
        rc.failed(0.0)  # a long outage: backoff at its cap
    assert not rc.due(100.0)  # absent: never tried, whatever the backoff says
    assert rc.wait_s(100.0, 0.2) == POLL_S
    port.touch()
    assert rc.due(0.5)  # back: at once, not after the backoff
    rc.failed(0.5)  # present but failing (e.g. permissions): backoff again
    assert not rc.due(0.6) and rc.due(1.5)


def test_only_local_paths_are_watched():
    assert local_path("/dev/ttyUSB0") == "/dev/ttyUSB0"
    assert local_path("tcp://127.0.0.1:8101") is None
    assert local_path("can0") is None and local_path("socket://h:1") is None
