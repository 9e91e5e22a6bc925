"""Sensor samples written straight from the simulation's arrays.

At 1,000 robots the simulator sends 40,000 samples per simulated second; building a PointCloud,
two Odometry and a Bumper per robot and encoding them cost more than the physics. The bytes on
the wire are fixed by the message types (docs/wire-format.md: msgspec Structs as msgpack maps,
every float a float64), so for one robot only the numbers change between periods. `SensorWire`
asks msgspec once for each robot's four payloads with marker values in every variable field,
finds where the markers landed (once per length of robot id: the layout depends on nothing
else), and from then on writes the numbers into those places for all robots at once with
numpy. The constant parts (map headers, field names, frame ids) are msgspec's own bytes, so the
result is exactly `codec.encode` of the message objects — the wire contract, checked by
tests/test_sim_wire.py.

One buffer holds a record per robot, in robot order: sonar | odom | ground truth | bumper, then
room for the bumper's collision count, the only field whose width varies (msgpack writes an int
in 1 to 9 bytes). Robots whose ids have different lengths have different layouts; each layout is
a numpy structured dtype over the same buffer (fields may sit at any byte offset), so a period
costs one assignment per layout, not one per robot.
"""

from __future__ import annotations

import operator
import struct
from collections.abc import Collection, Sequence

import numpy as np
from msgspec.structs import replace

from mrta_zenoh import codec, keys
from mrta_zenoh.messages import Header, Message, Odometry, Point2D, PointCloud, Pose2D, Twist

from .messages import Bumper

SONAR, ODOM, TRUTH, BUMP = range(4)  # the samples of a robot, in the order they are published
_INT_ROOM = 9  # msgpack's widest int: a type byte and 8 bytes


def bumper_key(robot_id: str) -> str:
    return f"{robot_id}/bumper"


def sample_keys(robot_id: str) -> tuple[str, str, str, str]:
    """The keys of one robot's samples, in SONAR, ODOM, TRUTH, BUMP order (the key contract)."""
    return keys.sonar(robot_id), keys.odom(robot_id), keys.ground_truth(robot_id), \
        bumper_key(robot_id)


def sample_messages(robot_id: str, t: float, points: Sequence[Sequence[float]],
                    odom: Sequence[float], odom_twist: Sequence[float], pose: Sequence[float],
                    vel: Sequence[float], stalled: bool, contact: bool, collisions: int
                    ) -> tuple[PointCloud, Odometry, Odometry, Bumper]:
    """One robot's four samples as message objects: what the bytes stand for (and what a ROS 2
    robot's driver is handed)."""
    return (PointCloud(Header(f"{robot_id}/sonar", t, 0), tuple(Point2D(x, y) for x, y in points)),
            Odometry(Header(f"{robot_id}/odom", t, 0), Pose2D(*odom), Twist(*odom_twist)),
            Odometry(Header("world", t, 0), Pose2D(*pose), Twist(*vel)),
            Bumper(Header(robot_id, t, 0), stalled, contact, collisions))


def _marker(i: int) -> float:
    """The i-th marker float. Its bytes hold 0xfe, which never occurs in UTF-8 text (field
    names, frame ids) nor in msgpack's framing of small maps and strings."""
    return struct.unpack(">d", b"\xc1\xfe" + i.to_bytes(6, "big"))[0]


def _find(payload: bytes, value: float) -> int:
    """Offset of the 8 bytes of a marker float in a payload; exactly one occurrence."""
    needle = b"\xcb" + struct.pack(">d", value)
    at = payload.find(needle)
    if at < 0 or payload.find(needle, at + 1) >= 0:
        raise RuntimeError(f"marker {value!r} not found exactly once in {payload!r}")
    return at + 1


def _marker_messages(robot_id: str, k: int) -> tuple[Message, ...]:
    """The robot's four messages with a distinct marker in each float field, False in the
    booleans and 0 as collision count. Marker i is column i of SensorWire's value matrix:
    sonar stamp, points; odom stamp, pose, twist; ground truth the same; bumper stamp."""
    n_float = 4 + 2 * k + 10
    mark = [_marker(i) for i in range(n_float)]
    pts = [(mark[1 + 2 * j], mark[2 + 2 * j]) for j in range(k)]
    o = 1 + 2 * k
    msgs = sample_messages(robot_id, mark[0], pts, mark[o + 1:o + 4], mark[o + 4:o + 6],
                           mark[o + 7:o + 10], mark[o + 10:o + 12], False, False, 0)
    return (msgs[0], _restamp(msgs[1], mark[o]), _restamp(msgs[2], mark[o + 6]),
            _restamp(msgs[3], mark[n_float - 1]))


def _restamp(msg: Message, stamp: float) -> Message:
    return replace(msg, header=replace(msg.header, stamp=stamp))


class _Layout:
    """Where a robot's numbers go in its record: the offsets of its float fields (in the column
    order of SensorWire's value matrix), of its two booleans and of its collision count, and
    where each of its four payloads starts — found in msgspec's own output for one robot.

    The layout depends only on the byte length of the robot's id (the one string of variable
    length in its samples), so robots whose ids are as long share it; `template` gives each
    its record, and `fixed` the bytes every record of this layout must hold where its numbers
    go (SensorWire checks all of them at once)."""

    def __init__(self, robot_id: str, k: int):
        self.k = k
        msgs = _marker_messages(robot_id, k)
        parts = [codec.encode(m) for m in msgs]
        self.starts = [0]
        for p in parts[:3]:
            self.starts.append(self.starts[-1] + len(p))
        self.floats = []
        column = 0
        for part, start, count in zip(parts, self.starts, (1 + 2 * k, 6, 6, 1)):
            for _ in range(count):
                self.floats.append(start + _find(part, _marker(column)))
                column += 1
        bump, base = parts[BUMP], self.starts[BUMP]
        stalled = codec.encode(replace(msgs[BUMP], stalled=True))
        contact = codec.encode(replace(msgs[BUMP], contact=True))
        self.bools = [base + _differing_byte(bump, stalled), base + _differing_byte(bump, contact)]
        if not bump.endswith(b"\x00"):  # collisions=0 is msgpack's one byte 0x00, last
            raise RuntimeError(f"bumper payload does not end with its collision count: {bump!r}")
        self.int_at = base + len(bump) - 1
        first = self.template(robot_id)
        at = [f + j for f in self.floats for j in range(-1, 8)] + self.bools + [self.int_at]
        self.fixed = (np.array(at, dtype=np.intp), np.frombuffer(first, dtype=np.uint8)[at])

    def template(self, robot_id: str) -> bytes:
        """The robot's record: its four marker payloads, then room for a wider count."""
        return b"".join(codec.encode(m) for m in _marker_messages(robot_id, self.k)) + \
            bytes(_INT_ROOM - 1)


def _differing_byte(a: bytes, b: bytes) -> int:
    diff = np.flatnonzero(np.frombuffer(a, dtype=np.uint8) != np.frombuffer(b, dtype=np.uint8)) \
        if len(a) == len(b) else ()
    if len(diff) != 1:
        raise RuntimeError("a boolean field does not change exactly one byte")
    return int(diff[0])


class SensorWire:
    """Encodes every robot's sonar, odometry, ground truth and bumper samples for one sensor
    period, as the bytes `codec.encode` would give for the message objects.

    `ids`: the robots, in the simulation's order; `k`: sonar points per robot; `omit`: robots
    whose sonar and odometry do not go out on our keys (ROS 2 robots: simulator/ros2.py) —
    their ground truth and bumper still do. `keys` and `encodings` list the samples `encode`
    returns, in that order: per robot, SONAR, ODOM, TRUTH, BUMP."""

    def __init__(self, ids: Sequence[str], k: int, omit: Collection[str] = ()):
        if k < 0:
            raise ValueError(f"sonar points per robot must be ≥ 0, got {k}")
        self.n, self.k = len(ids), k
        by_length: dict[int, _Layout] = {}
        layouts, templates = [], []
        for rid in ids:
            lay = by_length.get(len(rid.encode()))
            if lay is None:
                lay = by_length[len(rid.encode())] = _Layout(rid, k)
            layouts.append(lay)
            templates.append(lay.template(rid))
        size = max(map(len, templates)) if templates else 0
        self._buf = np.zeros((self.n, size), dtype=np.uint8)
        for i, template in enumerate(templates):
            self._buf[i, :len(template)] = np.frombuffer(template, dtype=np.uint8)
        self._n_float = 4 + 2 * k + 10
        self._floats_in = np.dtype({"names": [f"f{j}" for j in range(self._n_float)],
                                    "formats": ["<f8"] * self._n_float,
                                    "offsets": [8 * j for j in range(self._n_float)],
                                    "itemsize": 8 * self._n_float})
        self._bytes_in = np.dtype({"names": [f"b{j}" for j in range(2 + _INT_ROOM)],
                                   "formats": ["u1"] * (2 + _INT_ROOM),
                                   "offsets": list(range(2 + _INT_ROOM)),
                                   "itemsize": 2 + _INT_ROOM})
        # one (float view, byte view, rows) per distinct layout
        groups: dict[int, list[int]] = {}
        for i, lay in enumerate(layouts):
            groups.setdefault(id(lay), []).append(i)
        self._groups = []
        for rows in groups.values():
            lay = layouts[rows[0]]
            at, want = lay.fixed
            if not (self._buf[rows][:, at] == want).all():
                raise RuntimeError("robots whose ids are as long do not share a layout")
            floats = np.dtype({"names": self._floats_in.names, "formats": [">f8"] * self._n_float,
                               "offsets": lay.floats, "itemsize": size})
            small = np.dtype({"names": self._bytes_in.names, "formats": ["u1"] * (2 + _INT_ROOM),
                              "offsets": lay.bools + [lay.int_at + j for j in range(_INT_ROOM)],
                              "itemsize": size})
            contiguous = rows == list(range(rows[0], rows[-1] + 1))
            where = slice(rows[0], rows[-1] + 1) if contiguous else np.array(rows)
            self._groups.append((self._buf.view(floats).reshape(self.n),
                                 self._buf.view(small).reshape(self.n), where))
        # the payloads: slices of the buffer's bytes, in publishing order
        omit = set(omit)
        self.keys: list[str] = []
        self.encodings: list[str] = []
        self._slices: list[slice] = []
        self._bump_at: list[int] = []  # index in _slices of each robot's bumper payload
        self._int_at = [i * size + lay.int_at for i, lay in enumerate(layouts)]
        self._width = np.ones(self.n, dtype=np.int64)
        encs = (codec.encoding_for(PointCloud.TYPE_NAME), codec.encoding_for(Odometry.TYPE_NAME),
                codec.encoding_for(Odometry.TYPE_NAME), codec.encoding_for(Bumper.TYPE_NAME))
        for i, (rid, lay) in enumerate(zip(ids, layouts)):
            ends = lay.starts[1:] + [lay.int_at + 1]
            for kind, key in enumerate(sample_keys(rid)):
                if rid in omit and kind in (SONAR, ODOM):
                    continue
                if kind == BUMP:
                    self._bump_at.append(len(self._slices))
                self.keys.append(key)
                self.encodings.append(encs[kind])
                self._slices.append(slice(i * size + lay.starts[kind], i * size + ends[kind]))
        self._split = _splitter(self._slices)
        self.bump_rows = np.array(self._bump_at, dtype=np.intp)  # each robot's BUMP in `keys`
        self._values = np.empty((self.n, self._n_float))
        self._small = np.empty((self.n, 2 + _INT_ROOM), dtype=np.uint8)

    def encode(self, t: float, points: np.ndarray, odom: np.ndarray, odom_twist: np.ndarray,
               pose: np.ndarray, vel: np.ndarray, stalled: np.ndarray, contact: np.ndarray,
               collisions: np.ndarray) -> Sequence[bytes]:
        """The payloads of one period, in the order of `keys`. Arrays are per robot, in the
        simulation's order: points (n, k, 2), odom and pose (n, 3), odom_twist and vel (n, 2),
        stalled and contact (n,) booleans, collisions (n,) integers; `t` stamps them all."""
        n, k = self.n, self.k
        v = self._values
        o = 1 + 2 * k
        v[:, 0] = t
        v[:, 1:o] = np.reshape(points, (n, 2 * k))
        v[:, o] = t
        v[:, o + 1:o + 4] = odom
        v[:, o + 4:o + 6] = odom_twist
        v[:, o + 6] = t
        v[:, o + 7:o + 10] = pose
        v[:, o + 10:o + 12] = vel
        v[:, o + 12] = t
        small = self._small
        small[:, 0] = 0xc2
        small[:, 0] += np.asarray(stalled, dtype=bool)
        small[:, 1] = 0xc2
        small[:, 1] += np.asarray(contact, dtype=bool)
        width = msgpack_ints(np.asarray(collisions), small[:, 2:])
        floats_in = v.view(self._floats_in).reshape(n)
        bytes_in = small.view(self._bytes_in).reshape(n)
        for floats, smalls, where in self._groups:
            floats[where] = floats_in[where]
            smalls[where] = bytes_in[where]
        if not np.array_equal(width, self._width):
            self._resize(width)
        return self._split(self._buf.tobytes())

    def _resize(self, width: np.ndarray) -> None:
        """A collision count changed its msgpack width (127 → 128, …): its payload's end moves."""
        for i in np.flatnonzero(width != self._width).tolist():
            old = self._slices[self._bump_at[i]]
            self._slices[self._bump_at[i]] = slice(old.start, self._int_at[i] + int(width[i]))
        self._width = width.copy()
        self._split = _splitter(self._slices)


def _splitter(slices: list[slice]):
    """bytes → the tuple of its slices, in C (itemgetter: a third of a comprehension's cost)."""
    get = operator.itemgetter(*slices)
    return get if len(slices) > 1 else (lambda blob: (get(blob),))


# msgpack ints as msgspec writes them: the shortest form. (low, high, type byte or -1 for a
# fixint, bytes of the value kept from its 8 big-endian bytes)
_INT_FORMS = (
    (0, 1 << 7, -1, 1), (-32, 0, -1, 1),
    (1 << 7, 1 << 8, 0xcc, 1), (1 << 8, 1 << 16, 0xcd, 2), (1 << 16, 1 << 32, 0xce, 4),
    (1 << 32, None, 0xcf, 8),
    (-(1 << 7), -32, 0xd0, 1), (-(1 << 15), -(1 << 7), 0xd1, 2), (-(1 << 31), -(1 << 15), 0xd2, 4),
    (None, -(1 << 31), 0xd3, 8),
)


def msgpack_ints(values: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Write each int64 of `values` as msgpack into the rows of `out` (n, 9) uint8, left-aligned;
    returns the width of each (1, 2, 3, 5 or 9 bytes). Bytes past a width are left as they are."""
    values = values.astype(np.int64, copy=False)
    if values.size and 0 <= values.min() and values.max() < 128:  # the usual case
        out[:, 0] = values
        return np.ones(len(values), dtype=np.int64)
    big = values.astype(">i8").view(np.uint8).reshape(-1, 8)
    width = np.zeros(len(values), dtype=np.int64)
    for low, high, tag, size in _INT_FORMS:
        rows = np.ones(len(values), dtype=bool)
        if low is not None:
            rows &= values >= low
        if high is not None:
            rows &= values < high
        if not rows.any():
            continue
        if tag < 0:
            out[rows, 0] = big[rows, 7]
            width[rows] = 1
        else:
            out[rows, 0] = tag
            out[rows, 1:1 + size] = big[rows, 8 - size:]
            width[rows] = 1 + size
    return width
