"""Peer presence by token and by data (hilnav.peers.PeerTable), pure."""

from hilnav.peers import PeerTable


def test_a_silent_peer_is_dropped_after_the_timeout_and_readmitted_when_it_returns():
    t = PeerTable(timeout_s=1.0)
    assert t.seen("r2", 0.0) is True and t.seen("r2", 0.5) is False
    assert t.expire(1.4) == [] and t.alive == {"r2"}
    assert t.expire(1.6) == ["r2"] and t.alive == set()  # frozen: its token may still be up
    assert t.seen("r2", 3.0) is True and t.alive == {"r2"}  # back
    assert t.dropped == [("r2", "silent for 1 s")]


def test_a_token_that_goes_drops_the_peer_once():
    t = PeerTable(timeout_s=1.0)
    assert t.token("r3", True, 0.0) is False and t.alive == {"r3"}
    assert t.token("r3", False, 0.2) is True
    assert t.token("r3", False, 0.3) is False  # already gone
    assert t.expire(10.0) == [] and t.dropped == [("r3", "token gone")]


def test_a_token_alone_does_not_keep_a_peer_without_data():
    t = PeerTable(timeout_s=1.0)
    t.token("r4", True, 0.0)
    assert t.expire(1.5) == ["r4"]
