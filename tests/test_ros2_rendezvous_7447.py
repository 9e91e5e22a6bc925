"""The default rendezvous on a robot host, where rmw_zenohd holds 7447: a port held
by something that is not ours moves our rendezvous to the next free (or ours) port, with a
warning; a port held by one of ours is joined as before. DEFAULT_RENDEZVOUS is pointed at a free
port of this test, never at 7447."""

import logging
import socket

import pytest

from mrta_zenoh.bus import options
from mrta_zenoh.bus.options import BusOptions, session_configs


@pytest.fixture
def default_port(monkeypatch):
    """Three consecutive free ports; the default rendezvous set to the first."""
    for _ in range(50):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        if port + 3 < 65536 and all(options._port_free(port + i) for i in range(3)):
            break
    monkeypatch.setattr(options, "DEFAULT_RENDEZVOUS", f"tcp/127.0.0.1:{port}")
    monkeypatch.delenv(options.RENDEZVOUS_ENV, raising=False)
    return port


def _listen(port):
    s = socket.socket()
    s.bind(("127.0.0.1", port))
    s.listen()
    return s


def test_a_default_port_held_by_a_stranger_moves_the_rendezvous(default_port, caplog):
    stranger = _listen(default_port)  # no marker: not ours (as rmw_zenohd on 7447)
    try:
        with caplog.at_level(logging.WARNING, "mrta.bus"):
            rv = BusOptions().rendezvous_endpoint
        assert rv == f"tcp/127.0.0.1:{default_port + 1}"
        assert "not ours" in caplog.text and f":{default_port + 1}" in caplog.text
        bind, join = session_configs(BusOptions())
        assert rv in bind["listen"]["endpoints"] and join["connect"]["endpoints"] == [rv]
        # the process about to bind it holds its marker: the next one joins it, not the next port
        assert options._markers.get(default_port + 1) is not None
        held = _listen(default_port + 1)
        try:
            assert BusOptions().rendezvous_endpoint == rv
        finally:
            held.close()
    finally:
        stranger.close()
        options._markers.pop(default_port + 1).close()


def test_a_default_port_held_by_one_of_ours_is_joined(default_port):
    assert options._hold_marker(default_port)  # as our holder would
    held = _listen(default_port)
    try:
        assert BusOptions().rendezvous_endpoint == f"tcp/127.0.0.1:{default_port}"
    finally:
        held.close()
        options._markers.pop(default_port).close()


def test_an_explicit_rendezvous_is_used_as_given(default_port, monkeypatch):
    stranger = _listen(default_port)
    try:
        monkeypatch.setenv(options.RENDEZVOUS_ENV, f"tcp/127.0.0.1:{default_port}")
        assert BusOptions().rendezvous_endpoint == f"tcp/127.0.0.1:{default_port}"
    finally:
        stranger.close()
