"""`mrta secure init`: a certificate authority, one certificate per process, and the Zenoh
configs that make a fleet authenticated (mutual TLS to a router) and authorised (the router's
access control: a robot speaks only under its own `robotN/**`, observers only listen).

Generated, never hand-written, because a hand-written ACL is where a fleet's security quietly
fails. Roles (docs/security.md has the table and what each rule stops):

* **robot** (CN = robot id): may publish and declare liveliness tokens under `<id>/**`, its own
  lockstep keys (`@mrta/lockstep/done/<id>`, the token `@mrta/lockstep/participant/<id>`) and
  its ROS 2 side (topics under `<domain>/<id>/**`, node tokens in the ROS namespace `/<id>`),
  so the robot's own ROS 2 driver can run with its certificate; may subscribe to anything.
* **a registered role** (CN = the role's name): a program that is neither a robot nor an
  observer — the simulator — declares under the `mrta.secure.roles` entry-point group the keys
  it publishes on and the tokens it holds, and may do that and nothing more. The program knows
  its keys; this module only turns them into rules, so it never names another package's topics.
* **bridge** (`--bridge ROBOT` or `--bridge NAME=ROBOT,ROBOT`): a ROS 2 bridge for those robots
  only: their `odom` and `sonar` on our side, their ROS 2 topics, its own node's tokens.
* **submitter** (`--submitter NAME`, `mrta task … --as NAME`): may send task requests on its
  own `tasks/request/NAME` and hear the answers on `tasks/answer/NAME` (and whether the intake
  is up) — nothing else: it cannot speak for a robot or read the fleet's traffic. A fleet with
  submitters also gets the intake's certificate (`tasks`, the role mrta_zenoh.tasks registers).
* **an architecture's process** (`--process NAME`: central's `dispatcher`): the registered role
  of that name (its package states its keys), under a certificate of the same name.
* **observer** (supervisor, recorder, viewer…): may subscribe and watch liveliness, and hold a
  recorder token (`@mrta/recorder/<zid>`: the recorder and the viewer announce themselves);
  may not publish.
* anything without a certificate signed by the CA cannot even connect.

Beyond a plain mTLS set-up: certificates say which role they are for (OU),
only the router's certificate may serve TLS (the others are client-only: extended key usage
`clientAuth`, no host names), and clients verify the router's name; paths in the configs are
under `--root` (default: the folder's absolute path), so a copied folder still works; `--force`
replaces only the files this generator writes, never others in the folder.
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from .errors import ConfigError
from .files import write_atomically, write_folder
from .identity import BRIDGE, BRIDGE_URN, OBSERVER, ROBOT, SUBMITTER, bridge_node_name
from .installed import entry_points
from .keys import (RECORDER_TOKEN, ROS2_BRIDGE_TOKEN, KeyExprError, is_id,
                   normalize_robot_id, odom, sonar, validate_key_expr)
from .lockstep.protocol import DONE, PARTICIPANT
from .ros2.names import ADMIN_SPACE as ROS2_SPACE  # rmw_zenoh's liveliness space

DEFAULT_ENDPOINT = "tls/127.0.0.1:7448"
VALID_DAYS = 365
SIMULATOR = "simulator"  # the registered role `init(simulator=True)` adds (`--no-simulator`)
ROLE_GROUP = "mrta.secure.roles"
# what every role may subscribe to unless it says otherwise: `**` matches no chunk starting
# with `@`, so our infrastructure keys and ROS 2's graph are named beside it
EVERYTHING = ("**", "@mrta/**", f"{ROS2_SPACE}/**")
ORGANIZATION = "mrta-zenoh fleet"

DATA = ["put", "delete"]
# answering queries on a key (a queryable: the task intake's `tasks/history`, a late view's
# history) is saying what is on it: allowed where publishing is
ANSWER = ["declare_queryable", "reply"]
SUBSCRIBE = ["declare_subscriber", "declare_liveliness_subscriber", "liveliness_query", "query"]
TOKENS = ["liveliness_token"]
# What the router passes *to* every process: data and tokens it may see, and other processes'
# subscriber declarations — a publisher that never hears of a subscriber stops sending to it
# (write-side filtering), so without these only the first sample of a stream gets through.
DELIVER = DATA + TOKENS + ["declare_subscriber", "declare_liveliness_subscriber", "reply",
                           "query", "declare_queryable"]


@dataclass(frozen=True)
class Identity:
    name: str
    role: str  # robot | observer | bridge | the name of a registered role
    robots: tuple[str, ...] = ()  # a bridge's robots


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


# ------------------------------------------------------------------ certificates
def _name(common_name: str, role: str | None = None) -> x509.Name:
    attrs = [x509.NameAttribute(NameOID.COMMON_NAME, common_name),
             x509.NameAttribute(NameOID.ORGANIZATION_NAME, ORGANIZATION)]
    if role is not None:
        attrs.append(x509.NameAttribute(NameOID.ORGANIZATIONAL_UNIT_NAME, role))
    return x509.Name(attrs)


def _key() -> ec.EllipticCurvePrivateKey:
    return ec.generate_private_key(ec.SECP256R1())


def _pem_key(key) -> bytes:
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def _cert(subject: x509.Name, key, issuer_name: x509.Name, issuer_key, *, ca: bool = False,
          server_hosts: list[str] | None = None, uris: list[str] = ()) -> x509.Certificate:
    """A CA, the router's certificate (`server_hosts`: serves TLS for those names, and may
    connect to another router), or a client-only certificate: extended key usage `clientAuth`
    alone and no host name, so no TLS client accepts it as a server — a robot's key cannot
    impersonate the router."""
    now = datetime.datetime.now(datetime.timezone.utc)
    b = (x509.CertificateBuilder().subject_name(subject).issuer_name(issuer_name)
         .public_key(key.public_key()).serial_number(x509.random_serial_number())
         .not_valid_before(now - datetime.timedelta(minutes=5))
         .not_valid_after(now + datetime.timedelta(days=VALID_DAYS))
         .add_extension(x509.BasicConstraints(ca=ca, path_length=0 if ca else None),
                        critical=True))
    if ca:
        return b.add_extension(x509.KeyUsage(
            digital_signature=True, content_commitment=False, key_encipherment=False,
            data_encipherment=False, key_agreement=False, key_cert_sign=True, crl_sign=True,
            encipher_only=False, decipher_only=False), critical=True).sign(issuer_key,
                                                                           hashes.SHA256())
    b = b.add_extension(x509.KeyUsage(
        digital_signature=True, content_commitment=False, key_encipherment=False,
        data_encipherment=False, key_agreement=False, key_cert_sign=False, crl_sign=False,
        encipher_only=False, decipher_only=False), critical=True)
    alt: list[x509.GeneralName] = [x509.UniformResourceIdentifier(u) for u in uris]
    if server_hosts is not None:
        b = b.add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH,
                                                   ExtendedKeyUsageOID.CLIENT_AUTH]), critical=False)
        for h in server_hosts:
            try:
                alt.append(x509.IPAddress(ipaddress.ip_address(h)))
            except ValueError:
                alt.append(x509.DNSName(h))
    else:
        b = b.add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.CLIENT_AUTH]),
                            critical=False)
    if alt:
        b = b.add_extension(x509.SubjectAlternativeName(alt), critical=False)
    return b.sign(issuer_key, hashes.SHA256())


# ------------------------------------------------------------------ access control
def _ros2_node_tokens(domain: int, namespace_chunk: str, node: str = "") -> str:
    """rmw_zenoh's liveliness tokens of nodes in one namespace (mangled: `/robot1` → `%robot1`,
    the root namespace `%`), and of their publishers and subscriptions:
    `@ros2_lv/<domain>/<zid>/<nid>/<eid>/<kind>/<enclave>/<namespace>/<node>/…`."""
    return "/".join([ROS2_SPACE, str(domain), "*", "*", "*", "*", "*", namespace_chunk]
                    + ([node] if node else []) + ["**"])


def rules_for(identity: Identity, ros2_domain: int = 0) -> list[dict]:
    """The router's access-control rules for one identity (see the module docstring)."""
    n = identity.name
    everything = list(EVERYTHING)
    if identity.role == ROBOT:
        publish = [f"{n}/**", f"{DONE}/{n}", f"{ros2_domain}/{n}/**"]
        tokens = [f"{n}/**", f"{PARTICIPANT}/{n}", _ros2_node_tokens(ros2_domain, f"%{n}")]
        subscribe = everything
    elif identity.role == OBSERVER:
        publish, tokens, subscribe = [], [f"{RECORDER_TOKEN}/*"], everything
    elif identity.role == SUBMITTER:
        from .tasks.messages import answer_key, request_key
        from .tasks.server import TOKEN
        publish, tokens, subscribe = [request_key(n)], [], [answer_key(n), TOKEN]
    elif identity.role == BRIDGE:
        rs = identity.robots
        publish = [k for r in rs for k in (odom(r), sonar(r), f"{ros2_domain}/{r}/**")]
        tokens = [f"{ROS2_BRIDGE_TOKEN}/{r}" for r in rs] + [
            _ros2_node_tokens(ros2_domain, "%", bridge_node_name(rs))]
        subscribe = everything
    else:
        role = registered_role(identity.role)
        publish, tokens, subscribe = list(role.publish), list(role.tokens), list(role.subscribe)
    rules = [{"messages": DATA + ANSWER, "flows": ["ingress"], "key_exprs": publish},
             {"messages": TOKENS, "flows": ["ingress"], "key_exprs": tokens},
             {"messages": SUBSCRIBE, "flows": ["ingress"], "key_exprs": subscribe},
             {"messages": DELIVER, "flows": ["egress"], "key_exprs": everything}]
    return [r for r in rules if r["key_exprs"]]  # a rule on no key would not be valid


def access_control(identities: list[Identity], ros2_domain: int = 0) -> dict:
    rules, subjects, policies = [], [], []
    for ident in identities:
        subjects.append({"id": f"{ident.role}:{ident.name}", "cert_common_names": [ident.name]})
        ids = []
        for i, r in enumerate(rules_for(ident, ros2_domain)):
            rid = f"{ident.role}:{ident.name}:{i}"
            rules.append({"id": rid, "permission": "allow", **r})
            ids.append(rid)
        policies.append({"id": f"policy:{ident.name}", "rules": ids,
                         "subjects": [f"{ident.role}:{ident.name}"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}


# ------------------------------------------------------------------ Zenoh configs
def _tls(root: str, name: str, listen: bool) -> dict:
    def path(file: str) -> str:
        return f"{root.rstrip('/')}/{file}" if root else file

    tls = {"root_ca_certificate": path("ca.pem"), "enable_mtls": True,
           "connect_private_key": path(f"{name}.key"),
           "connect_certificate": path(f"{name}.pem"),
           # the router's certificate names the endpoint's host: a client talks to the fleet's
           # router only, not to whoever answers at that address with some fleet certificate
           "verify_name_on_connect": True}
    if listen:
        tls.update({"listen_private_key": path(f"{name}.key"),
                    "listen_certificate": path(f"{name}.pem")})
    return {"transport": {"link": {"tls": tls}}}


def router_config(root: str, endpoint: str, identities: list[Identity],
                  ros2_domain: int = 0) -> dict:
    cfg = {"mode": "router", "listen": {"endpoints": [endpoint]},
           "connect": {"endpoints": []},
           "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
           "access_control": access_control(identities, ros2_domain)}
    cfg.update(_tls(root, "router", listen=True))
    return cfg


def client_config(root: str, name: str, endpoint: str) -> dict:
    cfg = {"mode": "client", "connect": {"endpoints": [endpoint]}, "listen": {"endpoints": []},
           "scouting": {"multicast": {"enabled": False}}}
    cfg.update(_tls(root, name, listen=False))
    return cfg


# ------------------------------------------------------------------ the generator
def parse_bridge(spec: str) -> Identity:
    """`robot1` (a bridge for robot1, named `bridge-robot1`) or `NAME=robot1,robot2`."""
    name, sep, rest = spec.partition("=")
    if not sep:
        name, rest = "", spec
    robots = tuple(normalize_robot_id(r) for r in rest.split(",") if r.strip())
    if not robots:
        raise ConfigError(f"--bridge {spec!r}: expected ROBOT or NAME=ROBOT[,ROBOT…]")
    if len(set(robots)) != len(robots):
        raise ConfigError(f"--bridge {spec!r}: a robot is given twice")
    name = name.strip() or f"bridge-{robots[0]}"
    if not is_id(name):
        raise ConfigError(f"--bridge {spec!r}: name {name!r}: use letters, digits, '_', '-' "
                          "or '.'")
    return Identity(name, BRIDGE, robots)


def _identities(robots: list[str], observers: list[str], bridges: list[str],
                simulator: bool, submitters: list[str] = (),
                processes: list[str] = ()) -> list[Identity]:
    ids = [Identity(normalize_robot_id(r), ROBOT) for r in robots]
    if simulator:
        registered_role(SIMULATOR)  # a missing or broken registration fails before any key is made
        ids.append(Identity(SIMULATOR, SIMULATOR))
    for p in processes:  # an architecture's own process (central's dispatcher): its own role
        registered_role(p)
        ids.append(Identity(p, p))
    for o in observers:
        if not is_id(o):
            raise ConfigError(f"observer name {o!r}: use letters, digits, '_', '-' or '.'")
        ids.append(Identity(o, OBSERVER))
    ids += [parse_bridge(b) for b in bridges]
    for sub in submitters:
        if not is_id(sub):
            raise ConfigError(f"submitter name {sub!r}: use letters, digits, '_', '-' or '.'")
        ids.append(Identity(sub, SUBMITTER))
    if submitters:  # whoever submits needs the run's intake to answer it
        from .tasks.messages import INTAKE
        registered_role(INTAKE)
        ids.append(Identity(INTAKE, INTAKE))
    names = [i.name for i in ids] + ["router", "ca"]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise ConfigError(f"name {dupes[0]!r} is given twice (robots, observers, bridges and "
                          f"the reserved names router, ca, {SIMULATOR} must all differ)")
    if not ids:
        raise ConfigError("give at least one --robot, --observer or --bridge")
    robot_ids = {i.name for i in ids if i.role == ROBOT}
    for b in (i for i in ids if i.role == BRIDGE):
        unknown = [r for r in b.robots if r not in robot_ids]
        if unknown:
            raise ConfigError(f"bridge {b.name!r} is for {unknown[0]!r}, which is not a --robot "
                              "of this fleet")
    return ids


MANIFEST = "fleet-files.txt"  # the fleet's files, one per line: what --force may remove


def init(folder: Path, robots: list[str], observers: list[str], *,
         bridges: list[str] = (), endpoint: str = DEFAULT_ENDPOINT, simulator: bool = True,
         submitters: list[str] = (), processes: list[str] = (),
         force: bool = False, root: str | None = None, ros2_domain: int = 0) -> list[Path]:
    """Write ca.pem/ca.key, <name>.pem/.key per process, router.json5 and <name>.json5 into
    `folder` — all or nothing — and leave every other file there alone. Returns the files
    written.

    `root`: where the folder will be on the machines that use it (the configs name their
    certificates there); default: `folder`'s absolute path. `force`: replace files of a
    previous run; without it, a folder that already holds one of them is refused."""
    from .bus.options import check_endpoint

    check_endpoint(endpoint, "router endpoint")
    if not endpoint.startswith("tls/"):
        raise ConfigError(f"router endpoint {endpoint!r}: mutual TLS needs a tls/… endpoint")
    if not 0 <= ros2_domain <= 232:
        raise ConfigError(f"ROS 2 domain id {ros2_domain}: expected 0–232")
    ids = _identities(list(robots), list(observers), list(bridges), simulator, list(submitters),
                      list(processes))
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ConfigError("exists and is not a folder", file=str(folder))
    if root is None:
        root = str(folder.resolve())
    elif not root or "\n" in root or not Path(root).is_absolute():
        raise ConfigError(f"--root {root!r}: give the folder's absolute path on the machines "
                          "that will use it")
    host = endpoint.split("/", 1)[1].rsplit(":", 1)[0].strip("[]")

    files: dict[str, bytes] = {}
    ca_key = _key()
    ca_name = _name(f"{ORGANIZATION} CA")
    ca_cert = _cert(ca_name, ca_key, ca_name, ca_key, ca=True)
    files["ca.pem"] = ca_cert.public_bytes(serialization.Encoding.PEM)
    files["ca.key"] = _pem_key(ca_key)
    leaves = [("router", "router", sorted({host, "localhost"}), [])] + [
        (i.name, i.role, None, [f"{BRIDGE_URN}{r}" for r in i.robots]) for i in ids]
    for name, role, hosts, uris in leaves:
        key = _key()
        files[f"{name}.pem"] = _cert(_name(name, role), key, ca_cert.subject, ca_key,
                                     server_hosts=hosts, uris=uris).public_bytes(
            serialization.Encoding.PEM)
        files[f"{name}.key"] = _pem_key(key)
    files["router.json5"] = json.dumps(router_config(root, endpoint, ids, ros2_domain),
                                       indent=2).encode()
    for i in ids:
        files[f"{i.name}.json5"] = json.dumps(client_config(root, i.name, endpoint),
                                              indent=2).encode()
    modes = {n: 0o600 for n in files if n.endswith(".key")}  # private keys: the owner only
    # what this fleet is made of: a later --force removes the files of this fleet it does not
    # write again (robot1's certificate, signed by a CA that no longer exists, left beside the
    # new fleet's looked valid and was not)
    files[MANIFEST] = ("# written by mrta secure init: the files of this fleet\n"
                       + "".join(f"{n}\n" for n in sorted(files))).encode()
    if not folder.exists():
        return write_folder(folder, files, modes=modes)
    present = sorted(n for n in files if (folder / n).exists() or (folder / n).is_symlink())
    if present and not force:
        raise ConfigError(f"already holds {', '.join(present[:4])}"
                          f"{' …' if len(present) > 4 else ''}; use --force to replace the "
                          "files secure init writes (nothing else in the folder is touched)",
                          file=str(folder))
    stale = sorted(_manifest(folder) - set(files))
    written = _write_into(folder, files, modes)
    left = []
    for name in stale:
        try:
            (folder / name).unlink(missing_ok=True)
        except OSError:
            left.append(name)
    if left:
        raise ConfigError(f"the new fleet is written, but {', '.join(left)} of the previous one "
                          "could not be removed: remove them by hand", file=str(folder))
    return written


def _manifest(folder: Path) -> set[str]:
    """The files an earlier `secure init` wrote into `folder` (its manifest; plain names only:
    a manifest is never trusted to reach outside the folder)."""
    try:
        text = (folder / MANIFEST).read_text()
    except (OSError, UnicodeDecodeError):
        return set()
    return {n for n in (line.strip() for line in text.splitlines())
            if n and not n.startswith("#") and "/" not in n and n not in (".", "..")}


def _write_into(folder: Path, files: dict[str, bytes], modes: dict[str, int]) -> list[Path]:
    """`files` into an existing folder that holds other files too: all of them or none, and
    nothing else touched. Each is written through files.write_atomically (whole, beside its
    destination, renamed over it); the old contents are kept in memory (a fleet's files are a
    few kB each) and written back if one fails, and files that did not exist are removed."""
    old: dict[str, tuple[bytes, int] | None] = {}
    for name in files:
        target = folder / name
        if target.is_dir():
            raise ConfigError(f"{name} is a folder; nothing was changed", file=str(folder))
        try:
            old[name] = (target.read_bytes(), target.stat().st_mode & 0o777) \
                if target.exists() else None
        except OSError as exc:
            raise ConfigError(f"cannot read {name}: {exc.strerror}; nothing was changed",
                              file=str(folder)) from None
    done: list[str] = []
    try:
        for name, data in files.items():
            write_atomically(folder / name, _writer(data, modes.get(name)))
            done.append(name)
    except ConfigError as exc:
        for name in done:
            if old[name] is None:
                (folder / name).unlink(missing_ok=True)
            else:
                write_atomically(folder / name, _writer(*old[name]))
        raise ConfigError(f"{exc.detail}; nothing was changed", file=exc.file) from None
    return [folder / n for n in files]


def _writer(data: bytes, mode: int | None):
    """A write_atomically callback creating the file with `mode` from the start (a private key
    is never readable by others, not even for a moment)."""
    def write(tmp: Path) -> None:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666 if mode is None else mode)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
    return write
