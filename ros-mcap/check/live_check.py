#!/usr/bin/env python3
"""Independent client of the live view (`hil-sim run --live`, `wmr serve
--live`, `wmr-ros2 --live`), written from the published Foxglove WebSocket
protocol specification (github.com/foxglove/ws-protocol, docs/spec.md,
v1 messages) on the PyPI `websockets` package, and
checked against the MCAP log of the same run.

The client: opens ws://HOST:PORT offering the spec's subprotocol and
`foxglove.sdk.v1` (the name the `foxglove` crate 0.30.3 gives the same v1
messages; it refuses the spec's name with HTTP 400); reads the server's
JSON `serverInfo` and `advertise` (channels: id, topic, encoding,
schemaName, schema, schemaEncoding); sends one `subscribe` with a
subscription per channel; then reads binary `Message Data` frames (opcode
0x01, uint32 LE subscription id, uint64 LE timestamp ns, payload) until it
has every message of the run's log (complete once the run ended) and
closes, or until the server closes the connection.

First, the subprotocols book/src/how-to/foxglove.md states: a client offering only
`foxglove.websocket.v1` refused with HTTP 400, `foxglove.sdk.v1` alone
taken.

Checks against the log (read by the PyPI `mcap` package, decoded by
`rosbags`, neither ours):
1. the advertised channels are the log's: same topics, CDR, ros2msg, the
   same schema names and schema text;
2. per topic, the live messages are the log's: the same count, the same
   timestamps (the log time), the same bytes;
3. every /odom message decodes (rosbags, the Jazzy definition) to the
   log's values, field by field, and its stamp equals the message time.

4. with LAYOUT (book/src/how-to/foxglove-layout.json): every topic the layout's
   panels name is advertised, and every message path's first field is a
   field of that topic's schema (so the layout shows this stream and the
   log alike).

Two more modes, for a server that streams beyond its log (the client
reads until the server closes; `--ready FILE` is written once subscribed):

--tail (`wmr-ros2 --live --mcap`: the bridge logs and streams the same
frames, the client joins after the start): per topic the log's times
strictly increase (no repeated stamp: issue 35) and the live messages
are a contiguous run of the log's, the same times and bytes, at least
--min messages per topic but /diagnostics, ending at most 1 s before the
log's end.

--aligned (`wmr serve --live` beside `wmr record --mcap` through the
same server: both get every telemetry frame, each maps robot time to
host time with its own clock offset): per topic every log message
appears in the live stream, in order, with the same bytes except its
header stamp, which is the log's plus one constant for the whole run
(the two offsets' difference, found from /odom and then required of
every topic); /joint_states' wheel angles (each integrated from its own
start) advance by the same steps; /diagnostics (due on a change or a
period from each one's start) equal wherever both have one, at least
once. Checks 1 and 3 as above.

Usage: live_check.py [--tail|--aligned] [--min N] [--ready FILE] URL FILE.mcap [LAYOUT.json]
(exit 1 with the first mismatch). Prints one line per topic; "live check: all passed".
"""

import asyncio
import json
import struct
import sys

import websockets
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore

# The spec's name, and the name the `foxglove` crate (0.30.3) negotiates
# for the same v1 messages (it answers HTTP 400 to the spec's name alone:
# measured; book/src/how-to/foxglove.md).
SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]
OP_MESSAGE_DATA = 0x01


def fail(msg):
    print(f"live_check: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


async def receive(url, log, until_closed=False, ready=None):
    """Advertised channels {id: channel} and [(channel id, time ns, bytes)]:
    reads until the run's log is complete and every message it holds has
    come (then closes: `hil-sim run --live-wait` waits for its viewer to
    leave), or until the server closes (only that with `until_closed`);
    writes the file `ready` once subscribed."""
    channels = {}
    by_sub = {}
    got = []
    logged_total = None

    def log_total():
        try:
            _, msgs = read_log(log)
        except Exception:  # not there yet, or not finished: no footer
            return None
        return sum(len(v) for v in msgs.values())

    async with websockets.connect(url, subprotocols=SUBPROTOCOLS, max_size=None, proxy=None) as ws:
        if ws.subprotocol not in SUBPROTOCOLS:
            fail(f"server chose subprotocol {ws.subprotocol!r}")
        print(f"connected: subprotocol {ws.subprotocol}")
        subscribed = False
        try:
            while logged_total is None or len(got) < logged_total:
                try:
                    frame = await asyncio.wait_for(ws.recv(), 1.0)
                except asyncio.TimeoutError:
                    # Quiet: the run may be over; is its log complete?
                    if not until_closed:
                        logged_total = log_total()
                    continue
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    if msg.get("op") == "advertise":
                        for ch in msg["channels"]:
                            channels[ch["id"]] = ch
                        # Subscribe once every topic of the log is advertised
                        # (the server may advertise in several messages).
                        if not subscribed and len(channels) >= 5:
                            subs = []
                            for i, cid in enumerate(sorted(channels)):
                                by_sub[i] = cid
                                subs.append({"id": i, "channelId": cid})
                            await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                            subscribed = True
                            if ready:
                                open(ready, "w").close()
                    continue
                if frame[0] != OP_MESSAGE_DATA:
                    continue
                sub, t_ns = struct.unpack_from("<IQ", frame, 1)
                got.append((by_sub[sub], t_ns, bytes(frame[13:])))
                if len(got) % 500 == 0 and logged_total is None and not until_closed:
                    logged_total = log_total()
        except websockets.ConnectionClosed:
            pass
    return channels, got


async def spec_name_refused(url):
    """book/src/how-to/foxglove.md's claim about the subprotocols: a client offering
    only the spec's name is refused with HTTP 400 (the `foxglove` crate
    0.30.3 negotiates only `foxglove.sdk.v1` and `foxglove.sdk.v1.1`),
    and `foxglove.sdk.v1` alone is taken. If a server version takes the
    spec's name, this fails and the document must change."""
    try:
        async with websockets.connect(url, subprotocols=[SUBPROTOCOLS[0]], proxy=None) as ws:
            fail(f"the server took a client offering only {SUBPROTOCOLS[0]!r} (chose {ws.subprotocol!r}): book/src/how-to/foxglove.md says it refuses it")
    except websockets.InvalidStatus as e:
        if e.response.status_code != 400:
            fail(f"offering only {SUBPROTOCOLS[0]!r}: HTTP {e.response.status_code}, not 400")
    async with websockets.connect(url, subprotocols=[SUBPROTOCOLS[1]], proxy=None) as ws:
        if ws.subprotocol != SUBPROTOCOLS[1]:
            fail(f"offering only {SUBPROTOCOLS[1]!r}: the server chose {ws.subprotocol!r}")
    print(f"subprotocols: only {SUBPROTOCOLS[0]} refused (HTTP 400), only {SUBPROTOCOLS[1]} taken")


def read_log(path):
    with open(path, "rb") as f:
        r = make_reader(f)
        msgs = {}
        schemas = {}
        for schema, channel, message in r.iter_messages():
            schemas[channel.topic] = (channel.message_encoding, schema.name, schema.encoding, schema.data.decode())
            msgs.setdefault(channel.topic, []).append((message.log_time, bytes(message.data)))
    return schemas, msgs


def top_fields(schema_text):
    """Field names of a ros2msg schema's own message (before its first
    dependency separator)."""
    own = schema_text.split("\n====")[0]
    names = set()
    for line in own.splitlines():
        line = line.split("#")[0].strip()
        if line and "=" not in line:
            names.add(line.split()[1])
    return names


def check_layout(path, topics):
    with open(path) as f:
        layout = json.load(f)
    refs = []
    for panel in layout["configById"].values():
        for p in panel.get("paths", []):
            refs.append(p["value"])
        for key in ("topicPath", "topicToRender"):
            if key in panel:
                refs.append(panel[key])
        refs.extend(panel.get("topics", {}).keys())
    for ref in refs:
        topic = next((t for t in sorted(topics, key=len, reverse=True) if ref == t or ref.startswith(t + ".")), None)
        if topic is None:
            fail(f"layout names {ref!r}: not an advertised topic")
        rest = ref[len(topic) + 1:]
        if rest:
            field = rest.split(".")[0].split("[")[0]
            if field not in top_fields(topics[topic]["schema"]):
                fail(f"layout path {ref!r}: {topic} has no field {field!r}")
    print(f"layout {path}: {len(refs)} topic references, all advertised with their fields")


# Where each topic's (first) header stamp sits in its CDR bytes: after the
# 4-byte encapsulation header; in a TFMessage after its sequence length.
STAMP_AT = {"/tf": 8}


def masked(topic, data, stamp_from):
    """`data` with its header stamp (8 bytes: sec, nanosec) replaced by
    `stamp_from`'s."""
    k = STAMP_AT.get(topic, 4)
    return data[:k] + stamp_from[k:k + 8] + data[k + 8:]


def odom_pairs(pairs):
    """Check 3 on (live, logged) /odom pairs [(time, bytes)]: decoded
    values equal, the live stamp its message time. The count of values."""
    store = get_typestore(Stores.ROS2_JAZZY)
    fields = 0
    for (t, data), (_, logged_data) in pairs:
        o = store.deserialize_cdr(data, "nav_msgs/msg/Odometry")
        w = store.deserialize_cdr(logged_data, "nav_msgs/msg/Odometry")
        stamp = o.header.stamp.sec * 1_000_000_000 + o.header.stamp.nanosec
        if stamp != t:
            fail(f"/odom stamp {stamp} != message time {t}")
        p, q = o.pose.pose, w.pose.pose
        vals = [
            (p.position.x, q.position.x), (p.position.y, q.position.y),
            (p.orientation.z, q.orientation.z), (p.orientation.w, q.orientation.w),
            (o.twist.twist.linear.x, w.twist.twist.linear.x),
            (o.twist.twist.angular.z, w.twist.twist.angular.z),
        ] + list(zip(o.pose.covariance, w.pose.covariance)) + list(zip(o.twist.covariance, w.twist.covariance))
        for u, v in vals:
            if u != v:
                fail(f"/odom at {t}: decoded {u} != logged {v}")
        fields += len(vals)
    return fields


def exact(live, logged):
    for topic in sorted(logged):
        a, b = live.get(topic, []), logged[topic]
        if len(a) != len(b):
            fail(f"{topic}: {len(a)} live messages, {len(b)} in the log")
        for k, (x, y) in enumerate(zip(a, b)):
            if x[0] != y[0]:
                fail(f"{topic} message {k}: live time {x[0]} != log time {y[0]}")
            if x[1] != y[1]:
                fail(f"{topic} message {k}: bytes differ ({len(x[1])} live, {len(y[1])} logged)")
        print(f"{topic}: {len(a)} messages, times and bytes equal to the log")
    return list(zip(live["/odom"], logged["/odom"]))


def strictly_increasing(logged):
    for topic, msgs in sorted(logged.items()):
        for k in range(1, len(msgs)):
            if msgs[k][0] <= msgs[k - 1][0]:
                fail(f"log {topic}: message {k} time {msgs[k][0]} <= message {k - 1}'s {msgs[k - 1][0]} (a repeated stamp)")


def tail(live, logged, min_n):
    """The live messages: a contiguous run of the log's (the client joined
    after the start), reaching within 1 s of the log's end."""
    strictly_increasing(logged)
    for topic in sorted(logged):
        a, b = live.get(topic, []), logged[topic]
        if topic != "/diagnostics" and len(a) < min_n:
            fail(f"{topic}: {len(a)} live messages, fewer than {min_n}")
        if not a:
            continue
        j = next((k for k, m in enumerate(b) if m[0] == a[0][0]), None)
        if j is None:
            fail(f"{topic}: the first live time {a[0][0]} is not a log time")
        if a != b[j:j + len(a)]:
            k = next(k for k, (x, y) in enumerate(zip(a, b[j:] + [None] * len(a))) if x != y)
            fail(f"{topic}: live message {k} differs from log message {j + k} (time or bytes, or the log ended)")
        if b[-1][0] - a[-1][0] > 1_000_000_000:
            fail(f"{topic}: the live stream ended {(b[-1][0] - a[-1][0]) / 1e9:.2f} s before the log")
        print(f"{topic}: {len(a)} live messages = log messages {j}..{j + len(a) - 1} of {len(b)} (times, bytes); log times strictly increasing")
    j = next(k for k, m in enumerate(logged["/odom"]) if m[0] == live["/odom"][0][0])
    return list(zip(live["/odom"], logged["/odom"][j:]))


def aligned(live, logged):
    """Every log message in the live stream at its time plus one constant,
    the same bytes but for the stamp; returns the /odom pairs."""
    strictly_increasing(logged)
    a, b = live["/odom"], logged["/odom"]
    starts = []
    for j in range(len(a) - len(b) + 1):
        delta = a[j][0] - b[0][0]
        if all(a[j + k][0] - y[0] == delta and a[j + k][1] == masked("/odom", y[1], a[j + k][1])
               for k, y in enumerate(b)):
            starts.append((j, delta))
    if len(starts) != 1:
        fail(f"/odom: {len(starts)} places where the log's {len(b)} messages are a run of the {len(a)} live ones at one time offset (want 1)")
    j0, delta = starts[0]
    print(f"/odom: the log's {len(b)} messages = live messages {j0}..{j0 + len(b) - 1} (bytes but the stamp; live stamp = log stamp + {delta} ns)")
    store = get_typestore(Stores.ROS2_JAZZY)
    for topic in sorted(logged):
        if topic == "/odom":
            continue
        at = dict(live.get(topic, []))
        both = 0
        prev = None
        for t, data in logged[topic]:
            x = at.get(t + delta)
            if x is None:
                if topic == "/diagnostics":
                    continue
                fail(f"{topic}: no live message at the log's time {t} + {delta} ns")
            both += 1
            if topic != "/joint_states":
                if x != masked(topic, data, x):
                    fail(f"{topic} at log time {t}: bytes differ but for the stamp")
                continue
            o = store.deserialize_cdr(x, "sensor_msgs/msg/JointState")
            w = store.deserialize_cdr(data, "sensor_msgs/msg/JointState")
            if list(o.name) != list(w.name) or list(o.velocity) != list(w.velocity) or list(o.effort) != list(w.effort):
                fail(f"/joint_states at log time {t}: names, velocities or efforts differ")
            if prev is not None:
                for u, v, pu, pv in zip(o.position, w.position, prev[0], prev[1]):
                    if abs((u - pu) - (v - pv)) > 1e-9:
                        fail(f"/joint_states at log time {t}: wheel angle steps {u - pu} live, {v - pv} logged")
            prev = (list(o.position), list(w.position))
        if both == 0:
            fail(f"{topic}: no log message has a live one at the same time")
        print(f"{topic}: {both} of the log's {len(logged[topic])} messages in the live stream at log time + {delta} ns, equal but for the stamp"
              + (" (wheel angles: equal steps)" if topic == "/joint_states" else ""))
    return [(a[j0 + k], y) for k, y in enumerate(b)]


def main():
    import argparse
    ap = argparse.ArgumentParser(description="live view check", usage=__doc__)
    ap.add_argument("--tail", action="store_true")
    ap.add_argument("--aligned", action="store_true")
    ap.add_argument("--min", type=int, default=1)
    ap.add_argument("--ready")
    ap.add_argument("url")
    ap.add_argument("log")
    ap.add_argument("layout", nargs="?")
    args = ap.parse_args()
    asyncio.run(spec_name_refused(args.url))
    channels, got = asyncio.run(receive(args.url, args.log, args.tail or args.aligned, args.ready))
    schemas, logged = read_log(args.log)
    topics = {ch["topic"]: ch for ch in channels.values()}
    if set(topics) != set(schemas):
        fail(f"advertised topics {sorted(topics)} != the log's {sorted(schemas)}")
    for topic, (enc, name, schema_enc, text) in schemas.items():
        ch = topics[topic]
        mine = (ch["encoding"], ch["schemaName"], ch.get("schemaEncoding"), ch["schema"])
        if mine != (enc, name, schema_enc, text):
            fail(f"{topic}: advertised {mine[:3]} (schema {len(mine[3])} chars) != log {(enc, name, schema_enc)} ({len(text)} chars)")
    live = {}
    for cid, t, data in got:
        live.setdefault(channels[cid]["topic"], []).append((t, data))
    if "/odom" not in live:
        fail("no /odom message came")
    if args.tail:
        pairs = tail(live, logged, args.min)
    elif args.aligned:
        pairs = aligned(live, logged)
    else:
        pairs = exact(live, logged)
    fields = odom_pairs(pairs)
    print(f"/odom: {len(pairs)} messages decoded (rosbags, Jazzy), {fields} values equal to the log's")
    if args.layout:
        check_layout(args.layout, topics)
    print("live check: all passed")


if __name__ == "__main__":
    main()
