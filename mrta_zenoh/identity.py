"""Who a process is in a secured fleet, and refusing to start as someone else.

`mrta secure init` writes one certificate per process; its subject says the holder's name (CN)
and role (OU), and a bridge's certificate lists its robots (SAN URIs `urn:mrta-zenoh:bridge:ID`).
A process started with another's config would be muted by the router without a word — robot1
with robot2's certificate publishes under `robot1/**`, which robot2 may not — so a process that
knows who it is checks its certificate first (`check_identity`) and refuses to start, naming
the file. Kept apart from mrta_zenoh.secure so checking costs no certificate generator (the
`cryptography` import happens only when a certificate is read).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from .errors import ConfigError

ROBOT, OBSERVER, BRIDGE = "robot", "observer", "bridge"
SUBMITTER = "submitter"  # who submits tasks at run time (`mrta task`): its certificate names it
BRIDGE_URN = "urn:mrta-zenoh:bridge:"  # SAN URIs naming the robots a bridge certificate is for


def bridge_node_name(robots: list[str] | tuple[str, ...]) -> str:
    """The ROS 2 node name of a bridge for `robots` (its tokens are the only ones a bridge's
    certificate may declare, so the bridge and the access rules must agree on it)."""
    return f"mrta_bridge_{robots[0]}" if len(robots) == 1 else "mrta_bridge"


@dataclass(frozen=True)
class Certified:
    """What a fleet certificate says about its holder."""

    name: str                # CN
    role: str | None         # OU (None: a certificate from before roles were written)
    robots: tuple[str, ...]  # a bridge's robots
    path: str


def certified(config: Mapping, where: str) -> Certified | None:
    """The identity of the certificate a Zenoh config connects with, or None when the config
    uses no client certificate (an open bus). ConfigError if the certificate cannot be read."""
    link = config.get("transport", {}).get("link", {}) if isinstance(
        config.get("transport"), Mapping) else {}
    tls = link.get("tls") if isinstance(link, Mapping) else None
    path = tls.get("connect_certificate") if isinstance(tls, Mapping) else None
    if not path:
        return None
    if not isinstance(path, str):
        raise ConfigError(f"transport/link/tls/connect_certificate must be a path, got {path!r}",
                          file=where)
    from cryptography import x509
    from cryptography.x509.oid import NameOID

    try:
        cert = x509.load_pem_x509_certificate(Path(path).read_bytes())
    except OSError as exc:
        raise ConfigError(f"its certificate {path} cannot be read ({exc.strerror}); if the "
                          "fleet's folder was copied elsewhere, generate it with `mrta secure "
                          "init --root` naming where it lives", file=where) from None
    except ValueError as exc:
        raise ConfigError(f"its certificate {path} is not a PEM certificate: {exc}",
                          file=where) from None

    def attr(oid) -> str | None:
        found = cert.subject.get_attributes_for_oid(oid)
        return str(found[0].value) if found else None

    try:
        alt = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        uris = alt.get_values_for_type(x509.UniformResourceIdentifier)
    except x509.ExtensionNotFound:
        uris = []
    return Certified(attr(NameOID.COMMON_NAME) or "", attr(NameOID.ORGANIZATIONAL_UNIT_NAME),
                     tuple(u[len(BRIDGE_URN):] for u in uris if u.startswith(BRIDGE_URN)), path)


def check_identity(options, role: str, name: str | None = None,
                   robots: tuple[str, ...] | list[str] = ()) -> None:
    """Refuse to start a process whose fleet certificate is not its own: the router would
    silently drop everything it is not allowed to say (robot1 running with robot2's config
    publishes into the void). `options`: BusOptions; `role`: robot, observer, bridge or a
    registered role's name (`simulator`); `name`: the robot id for a robot; `robots`: a
    bridge's. Nothing to check on an open bus (no client certificate in the config).

    A certificate without a role (generated before roles were written) is checked by name."""
    if options.zenoh_config is None:
        return
    where = str(options.zenoh_config)
    cert = certified(options.user_config(), where)
    if cert is None:
        return
    want = name if role in (ROBOT, SUBMITTER) else (role if role not in (OBSERVER, BRIDGE) else None)
    holder = f"{cert.role} {cert.name}" if cert.role else cert.name
    if cert.role is not None and cert.role != role:
        raise ConfigError(f"its certificate {cert.path} is for {holder}, not for "
                          f"{_describe(role, name)}: start this process with the config "
                          "`mrta secure init` wrote for it", file=where)
    if want is not None and cert.name != want:
        raise ConfigError(f"its certificate {cert.path} is for {holder}, not for "
                          f"{_describe(role, name)}: the router would drop everything it says; "
                          f"use {want}.json5", file=where)
    missing = [r for r in robots if r not in cert.robots]
    if role == BRIDGE and missing:
        raise ConfigError(f"its certificate {cert.path} is for a bridge for "
                          f"{', '.join(cert.robots) or 'no robot'}, not for {missing[0]}: "
                          "generate one with `mrta secure init --bridge NAME=ROBOT,…`",
                          file=where)


def _describe(role: str, name: str | None) -> str:
    if role == ROBOT:
        return f"robot {name}"
    return {OBSERVER: "an observer", BRIDGE: "a bridge"}.get(role, f"the {role}")
