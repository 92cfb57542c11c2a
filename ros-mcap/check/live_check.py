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

Usage: live_check.py URL FILE.mcap [LAYOUT.json]   (exit 1 with the first mismatch)
Prints one line per topic; "live check: all passed".
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


async def receive(url, log):
    """Advertised channels {id: channel} and [(channel id, time ns, bytes)]:
    reads until the run's log is complete and every message it holds has
    come (then closes: `hil-sim run --live-wait` waits for its viewer to
    leave), or until the server closes."""
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
                    continue
                if frame[0] != OP_MESSAGE_DATA:
                    continue
                sub, t_ns = struct.unpack_from("<IQ", frame, 1)
                got.append((by_sub[sub], t_ns, bytes(frame[13:])))
                if len(got) % 500 == 0 and logged_total is None:
                    logged_total = log_total()
        except websockets.ConnectionClosed:
            pass
    return channels, got


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


def main():
    if len(sys.argv) not in (3, 4):
        fail(__doc__)
    url, log = sys.argv[1], sys.argv[2]
    channels, got = asyncio.run(receive(url, log))
    schemas, logged = read_log(log)
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
    for topic in sorted(schemas):
        a, b = live.get(topic, []), logged[topic]
        if len(a) != len(b):
            fail(f"{topic}: {len(a)} live messages, {len(b)} in the log")
        for k, (x, y) in enumerate(zip(a, b)):
            if x[0] != y[0]:
                fail(f"{topic} message {k}: live time {x[0]} != log time {y[0]}")
            if x[1] != y[1]:
                fail(f"{topic} message {k}: bytes differ ({len(x[1])} live, {len(y[1])} logged)")
        print(f"{topic}: {len(a)} messages, times and bytes equal to the log")
    store = get_typestore(Stores.ROS2_JAZZY)
    fields = 0
    for (t, data), (_, logged_data) in zip(live["/odom"], logged["/odom"]):
        o = store.deserialize_cdr(data, "nav_msgs/msg/Odometry")
        w = store.deserialize_cdr(logged_data, "nav_msgs/msg/Odometry")
        stamp = o.header.stamp.sec * 1_000_000_000 + o.header.stamp.nanosec
        if stamp != t:
            fail(f"/odom stamp {stamp} != message time {t}")
        p, q = o.pose.pose, w.pose.pose
        pairs = [
            (p.position.x, q.position.x), (p.position.y, q.position.y),
            (p.orientation.z, q.orientation.z), (p.orientation.w, q.orientation.w),
            (o.twist.twist.linear.x, w.twist.twist.linear.x),
            (o.twist.twist.angular.z, w.twist.twist.angular.z),
        ] + list(zip(o.pose.covariance, w.pose.covariance)) + list(zip(o.twist.covariance, w.twist.covariance))
        for u, v in pairs:
            if u != v:
                fail(f"/odom at {t}: decoded {u} != logged {v}")
        fields += len(pairs)
    print(f"/odom: {len(live['/odom'])} messages decoded (rosbags, Jazzy), {fields} values equal to the log's")
    if len(sys.argv) == 4:
        check_layout(sys.argv[3], topics)
    print("live check: all passed")


if __name__ == "__main__":
    main()
