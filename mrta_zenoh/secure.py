"""`mrta secure init`: a certificate authority, one certificate per process, and the Zenoh
configs that make a fleet authenticated (mutual TLS to a router) and authorised (the router's
access control: a robot speaks only under its own `robotN/**`, observers only listen).

Generated, never hand-written, because a hand-written ACL is where a fleet's security quietly
fails. Roles:

* **robot** (CN = robot id): may publish and declare liveliness tokens under `<id>/**`; may
  subscribe to anything (teammates' broadcasts, its sensors, the clock).
* **a registered role** (CN = the role's name): a program that is neither a robot nor an
  observer — the simulator — declares under the `mrta.secure.roles` entry-point group the keys
  it publishes on and the tokens it holds, and may do that and nothing more. The program knows
  its keys; this module only turns them into rules, so it never names another package's topics.
* **observer** (supervisor, recorder, …): may subscribe and watch liveliness; may not publish
  and may not declare tokens.
* anything without a certificate signed by the CA cannot even connect.

What holds and what does not is in docs/security.md (measured, with the tests that show it).
"""

from __future__ import annotations

import datetime
import ipaddress
import json
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from .errors import ConfigError
from .files import write_folder
from .keys import KeyExprError, is_id, normalize_robot_id, validate_key_expr

DEFAULT_ENDPOINT = "tls/127.0.0.1:7448"
VALID_DAYS = 365
SIMULATOR = "simulator"  # the registered role `init(simulator=True)` adds (`--no-simulator`)
ROLE_GROUP = "mrta.secure.roles"
EVERYTHING = ("**", "@mrta/**")  # what every role may subscribe to unless it says otherwise

DATA = ["put", "delete"]
SUBSCRIBE = ["declare_subscriber", "declare_liveliness_subscriber", "liveliness_query", "query"]
TOKENS = ["liveliness_token"]
# What the router passes *to* every process: data and tokens it may see, and other processes'
# subscriber declarations — a publisher that never hears of a subscriber stops sending to it
# (write-side filtering), so without these only the first sample of a stream gets through.
DELIVER = DATA + TOKENS + ["declare_subscriber", "declare_liveliness_subscriber", "reply"]


@dataclass(frozen=True)
class Identity:
    name: str
    role: str  # robot | observer | the name of a registered role


@dataclass(frozen=True)
class Role:
    """What a registered role may do: publish (put, delete) on `publish`, declare liveliness
    tokens under `tokens`, subscribe and query on `subscribe`."""

    publish: tuple[str, ...] = ()
    tokens: tuple[str, ...] = ()
    subscribe: tuple[str, ...] = EVERYTHING


def registered_role(name: str) -> Role:
    """The role `name` as its package registers it under `mrta.secure.roles`: a mapping, or a
    function returning one, with `publish`, `tokens` and optionally `subscribe` (lists of key
    expressions). ConfigError if none is registered or it is malformed: a fleet generated from a
    guess would either not run or let a process do more than it should."""
    found = [ep for ep in entry_points(group=ROLE_GROUP) if ep.name == name]
    if not found:
        known = sorted({ep.name for ep in entry_points(group=ROLE_GROUP)})
        raise ConfigError(f"no role {name!r} is registered under the {ROLE_GROUP} entry points "
                          f"(registered: {', '.join(known) or 'none'}); is its package installed?")
    ep = found[0]
    where = f"role {name!r} ({ep.value})"
    try:
        spec = ep.load()
    except (ImportError, AttributeError) as exc:
        raise ConfigError(f"{where} cannot be loaded: {exc}") from None
    if callable(spec):
        spec = spec()
    if not isinstance(spec, Mapping):
        raise ConfigError(f"{where} must give a mapping of publish/tokens/subscribe, "
                          f"got {type(spec).__name__}")
    unknown = sorted(set(spec) - {"publish", "tokens", "subscribe"})
    if unknown:
        raise ConfigError(f"{where}: unknown entry {unknown[0]!r} (expected publish, tokens, "
                          "subscribe)")
    lists = {}
    for what, value in spec.items():
        if isinstance(value, str) or not isinstance(value, (list, tuple)) \
                or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{where}: {what!r} must be a list of key expressions")
        try:
            lists[what] = tuple(validate_key_expr(v) for v in value)
        except KeyExprError as exc:
            raise ConfigError(f"{where}: {what!r}: {exc}") from None
    return Role(**lists)


def _name(common_name: str) -> x509.Name:
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name),
                      x509.NameAttribute(NameOID.ORGANIZATION_NAME, "mrta-zenoh fleet")])


def _key() -> ec.EllipticCurvePrivateKey:
    return ec.generate_private_key(ec.SECP256R1())


def _pem_key(key) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def _cert(subject: str, key, issuer_name: x509.Name, issuer_key, ca: bool,
          hosts: list[str] = ()) -> x509.Certificate:
    now = datetime.datetime.now(datetime.timezone.utc)
    b = (x509.CertificateBuilder().subject_name(_name(subject)).issuer_name(issuer_name)
         .public_key(key.public_key()).serial_number(x509.random_serial_number())
         .not_valid_before(now - datetime.timedelta(minutes=5))
         .not_valid_after(now + datetime.timedelta(days=VALID_DAYS))
         .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True))
    if ca:
        b = b.add_extension(x509.KeyUsage(True, False, False, False, False, True, True, False,
                                          False), critical=True)
    else:
        b = b.add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                   ExtendedKeyUsageOID.CLIENT_AUTH]), critical=False)
        alt = [x509.DNSName(subject) if is_id(subject) else x509.DNSName("mrta")]
        for h in hosts:
            try:
                alt.append(x509.IPAddress(ipaddress.ip_address(h)))
            except ValueError:
                alt.append(x509.DNSName(h))
        b = b.add_extension(x509.SubjectAlternativeName(alt), critical=False)
    return b.sign(issuer_key, hashes.SHA256())


def rules_for(identity: Identity) -> list[dict]:
    """The router's access-control rules for one identity (see the module docstring)."""
    n = identity.name
    everything = list(EVERYTHING)
    if identity.role == "robot":
        return [
            {"messages": DATA, "flows": ["ingress"], "key_exprs": [f"{n}/**"]},
            {"messages": TOKENS, "flows": ["ingress"], "key_exprs": [f"{n}/**"]},
            {"messages": SUBSCRIBE, "flows": ["ingress"], "key_exprs": everything},
            {"messages": DELIVER, "flows": ["egress"], "key_exprs": everything},
        ]
    if identity.role == "observer":
        return [
            {"messages": SUBSCRIBE, "flows": ["ingress"], "key_exprs": everything},
            {"messages": DELIVER, "flows": ["egress"], "key_exprs": everything},
        ]
    role = registered_role(identity.role)
    rules = [{"messages": DATA, "flows": ["ingress"], "key_exprs": list(role.publish)},
             {"messages": TOKENS, "flows": ["ingress"], "key_exprs": list(role.tokens)},
             {"messages": SUBSCRIBE, "flows": ["ingress"], "key_exprs": list(role.subscribe)},
             {"messages": DELIVER, "flows": ["egress"], "key_exprs": everything}]
    return [r for r in rules if r["key_exprs"]]  # a rule on no key would not be valid


def access_control(identities: list[Identity]) -> dict:
    rules, subjects, policies = [], [], []
    for ident in identities:
        subjects.append({"id": f"{ident.role}:{ident.name}", "cert_common_names": [ident.name]})
        ids = []
        for i, r in enumerate(rules_for(ident)):
            rid = f"{ident.role}:{ident.name}:{i}"
            rules.append({"id": rid, "permission": "allow", **r})
            ids.append(rid)
        policies.append({"id": f"policy:{ident.name}", "rules": ids,
                         "subjects": [f"{ident.role}:{ident.name}"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}


def _tls(folder: Path, name: str, listen: bool) -> dict:
    tls = {"root_ca_certificate": str(folder / "ca.pem"), "enable_mtls": True,
           "connect_private_key": str(folder / f"{name}.key"),
           "connect_certificate": str(folder / f"{name}.pem"),
           "verify_name_on_connect": False}
    if listen:
        tls.update({"listen_private_key": str(folder / f"{name}.key"),
                    "listen_certificate": str(folder / f"{name}.pem")})
    return {"transport": {"link": {"tls": tls}}}


def router_config(folder: Path, endpoint: str, identities: list[Identity]) -> dict:
    cfg = {"mode": "router", "listen": {"endpoints": [endpoint]},
           "connect": {"endpoints": []},
           "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
           "access_control": access_control(identities)}
    cfg.update(_tls(folder, "router", listen=True))
    return cfg


def client_config(folder: Path, name: str, endpoint: str) -> dict:
    cfg = {"mode": "client", "connect": {"endpoints": [endpoint]}, "listen": {"endpoints": []},
           "scouting": {"multicast": {"enabled": False}}}
    cfg.update(_tls(folder, name, listen=False))
    return cfg


def init(folder: Path, robots: list[str], observers: list[str], *,
         endpoint: str = DEFAULT_ENDPOINT, simulator: bool = True, force: bool = False) -> list[Path]:
    """Write ca.pem/ca.key, <name>.pem/.key per process, router.json5 and <name>.json5 into
    `folder` — all or nothing. Returns the files written."""
    from .bus.options import check_endpoint

    check_endpoint(endpoint, "router endpoint")
    if not endpoint.startswith("tls/"):
        raise ConfigError(f"router endpoint {endpoint!r}: mutual TLS needs a tls/… endpoint")
    ids = [Identity(normalize_robot_id(r), "robot") for r in robots]
    if simulator:
        registered_role(SIMULATOR)  # a missing or broken registration fails before any key is made
        ids.append(Identity(SIMULATOR, SIMULATOR))
    for o in observers:
        if not is_id(o):
            raise ConfigError(f"observer name {o!r}: use letters, digits, '_', '-' or '.'")
        ids.append(Identity(o, "observer"))
    names = [i.name for i in ids] + ["router", "ca"]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ConfigError(f"name {dupes[0]!r} is given twice (robots, observers, and the "
                          f"reserved names router, ca, {SIMULATOR} must all differ)")
    if not ids:
        raise ConfigError("give at least one --robot or --observer")
    folder = Path(folder)
    if folder.exists() and any(folder.iterdir()) and not force:
        raise ConfigError(f"{folder} is not empty; use --force to replace its files")
    host = endpoint.split("/", 1)[1].rsplit(":", 1)[0].strip("[]")

    files: dict[str, bytes] = {}
    ca_key = _key()
    ca_cert = _cert("mrta-zenoh fleet CA", ca_key, _name("mrta-zenoh fleet CA"), ca_key, ca=True)
    files["ca.pem"] = ca_cert.public_bytes(serialization.Encoding.PEM)
    files["ca.key"] = _pem_key(ca_key)
    for name, hosts in [("router", [host, "localhost"])] + [(i.name, []) for i in ids]:
        key = _key()
        files[f"{name}.pem"] = _cert(name, key, ca_cert.subject, ca_key, ca=False,
                                     hosts=hosts).public_bytes(serialization.Encoding.PEM)
        files[f"{name}.key"] = _pem_key(key)
    target = folder.resolve()
    files["router.json5"] = json.dumps(router_config(target, endpoint, ids), indent=2).encode()
    for i in ids:
        files[f"{i.name}.json5"] = json.dumps(client_config(target, i.name, endpoint),
                                              indent=2).encode()
    # everything or nothing, private keys readable by their owner only
    return write_folder(folder, files, modes={n: 0o600 for n in files if n.endswith(".key")})
