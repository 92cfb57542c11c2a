#!/usr/bin/env python3
"""Independent reader check of a ros-mcap log (`hil-sim run --mcap`,
`wmr record --mcap`) against the trace CSV of the same run.

Readers not ours: the PyPI `mcap` package reads the file, `rosbags` parses
each channel's ros2msg schema and decodes (and re-encodes) every CDR
message. Checks:

1. every channel is CDR with a ros2msg schema; the schemas of the standard
   types define exactly the fields of the ROS 2 Jazzy definitions rosbags
   ships (wmr_msgs/msg/Tracking is parsed from the file's own schema);
2. every message decodes, and rosbags' own CDR encoding of the decoded
   message is byte for byte the file's;
3. header stamps equal the log times and never go back;
4. the values equal the CSV's rows: /wmr/tracking while running or stopping
   column by column (bit-exact: both are the same f64), /odom and /tf the
   CSV's pose of G moved d back to the axle midpoint, the twist eta,
   /joint_states (v +- h w)/r and the torque, /diagnostics' level and
   health for the row it was written with.

Usage: mcap_check.py FILE.mcap FILE.csv   (exit 1 with the first mismatch)
"""

import csv
import math
import sys

from mcap.reader import make_reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

STANDARD = (
    "nav_msgs/msg/Odometry",
    "tf2_msgs/msg/TFMessage",
    "sensor_msgs/msg/JointState",
    "diagnostic_msgs/msg/DiagnosticArray",
)
TOPICS = {
    "/odom": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "/wmr/tracking": "wmr_msgs/msg/Tracking",
}
RUNNING, STOPPING = 1, 2


def fail(msg):
    print(f"mcap_check: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def same(a, b, tol=0.0):
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return abs(a - b) <= tol * max(1.0, abs(a))


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        fail(f"{path}: no rows")
    return [{k: float(v) for k, v in r.items()} for r in rows]


def main(mcap_path, csv_path):
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    store = get_typestore(Stores.EMPTY)
    with open(mcap_path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        if "wmr" not in meta:
            fail("no 'wmr' metadata record")
        geo = meta["wmr"]
        r, h, d = (float(geo[k]) for k in ("wheel_radius_m", "half_track_m", "com_offset_m"))
        # 1. schemas
        for ch in summary.channels.values():
            sc = summary.schemas[ch.schema_id]
            if ch.message_encoding != "cdr" or sc.encoding != "ros2msg":
                fail(f"{ch.topic}: encoding {ch.message_encoding}/{sc.encoding}")
            if TOPICS.get(ch.topic) != sc.name:
                fail(f"{ch.topic}: schema {sc.name}")
            types = get_types_from_msg(sc.data.decode(), sc.name)
            if sc.name in STANDARD:
                for name, defs in types.items():
                    if name not in jazzy.fielddefs:
                        fail(f"{sc.name}: {name} is not a Jazzy type")
                    ours = [(f, str(t)) for f, t in defs[1]]
                    theirs = [(f, str(t)) for f, t in jazzy.fielddefs[name][1]]
                    if ours != theirs:
                        fail(f"{name}: fields {ours} differ from Jazzy's {theirs}")
            store.register(types)
        if set(TOPICS) - {c.topic for c in summary.channels.values()}:
            fail(f"topics missing: {set(TOPICS) - {c.topic for c in summary.channels.values()}}")
        # 2. decode and re-encode every message
        msgs = {t: [] for t in TOPICS}
        count = 0
        last_time = {}
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            ty = TOPICS[channel.topic]
            m = store.deserialize_cdr(message.data, ty)
            again = bytes(store.serialize_cdr(m, ty))
            if again != bytes(message.data):
                fail(f"{channel.topic}: rosbags encodes message {count} differently")
            # 3. stamps
            stamp = (m.transforms[0].header if ty == "tf2_msgs/msg/TFMessage" else m.header).stamp
            ns = stamp.sec * 1_000_000_000 + stamp.nanosec
            if ns != message.log_time:
                fail(f"{channel.topic}: header stamp {ns} != log time {message.log_time}")
            if message.log_time < last_time.get(channel.topic, 0):
                fail(f"{channel.topic}: time goes back at message {count}")
            last_time[channel.topic] = message.log_time
            msgs[channel.topic].append((message.log_time, m))
            count += 1
    n = len(msgs["/wmr/tracking"])
    for t in ("/odom", "/tf", "/joint_states"):
        if len(msgs[t]) != n:
            fail(f"{t}: {len(msgs[t])} messages, /wmr/tracking has {n}")
    if not msgs["/diagnostics"]:
        fail("no /diagnostics message")
    # 4. values against the CSV
    rows = read_csv(csv_path)
    running = [i for i, (_, m) in enumerate(msgs["/wmr/tracking"]) if m.state in (RUNNING, STOPPING)]
    if len(running) != len(rows):
        fail(f"{len(running)} running/stopping tracking messages, the CSV has {len(rows)} rows")
    pairs = [
        ("t_s", lambda m: m.t_s),
        ("ref_x_m", lambda m: m.ref_pose[0]), ("ref_y_m", lambda m: m.ref_pose[1]),
        ("ref_theta_rad", lambda m: m.ref_pose[2]),
        ("x_m", lambda m: m.pose[0]), ("y_m", lambda m: m.pose[1]), ("theta_rad", lambda m: m.pose[2]),
        ("pos_err_m", lambda m: m.pos_err_m),
        ("err_x_m", lambda m: m.err_xy_m[0]), ("err_y_m", lambda m: m.err_xy_m[1]),
        ("e_x", lambda m: m.e[0]), ("e_y", lambda m: m.e[1]), ("e_theta", lambda m: m.e[2]),
        ("v_mps", lambda m: m.eta[0]), ("omega_radps", lambda m: m.eta[1]),
        ("v_c_mps", lambda m: m.eta_c[0]), ("omega_c_radps", lambda m: m.eta_c[1]),
        ("tau_r_nm", lambda m: m.torque_nm[0]), ("tau_l_nm", lambda m: m.torque_nm[1]),
        ("s_v", lambda m: m.s[0]), ("s_omega", lambda m: m.s[1]),
        ("rho_hat_v", lambda m: m.rho_hat[0]), ("rho_hat_omega", lambda m: m.rho_hat[1]),
        ("d_hat_v", lambda m: m.d_hat[0]), ("d_hat_omega", lambda m: m.d_hat[1]),
        ("f_hat_v", lambda m: m.f_hat[0]), ("f_hat_omega", lambda m: m.f_hat[1]),
        ("f_true_v", lambda m: m.f_true[0]), ("f_true_omega", lambda m: m.f_true[1]),
        ("saturated", lambda m: float(m.saturated)),
        ("time_scale", lambda m: m.time_scale), ("tau_s", lambda m: m.tau_s),
        ("health", lambda m: float(m.health)), ("health_reason", lambda m: float(m.health_reason)),
    ]
    if set(p for p, _ in pairs) != set(rows[0]):
        fail(f"CSV columns {sorted(rows[0])} are not the checked ones")
    checked = 0
    for row, i in zip(rows, running):
        tr = msgs["/wmr/tracking"][i][1]
        for col, get in pairs:
            if not same(row[col], float(get(tr))):
                fail(f"row {checked}: {col} CSV {row[col]} != MCAP {get(tr)}")
        x, y, th = row["x_m"], row["y_m"], row["theta_rad"]
        bx, by = x - d * math.cos(th), y - d * math.sin(th)
        odo = msgs["/odom"][i][1]
        if odo.header.frame_id != "odom" or odo.child_frame_id != "base_link":
            fail(f"/odom frames {odo.header.frame_id} -> {odo.child_frame_id}")
        p, q = odo.pose.pose.position, odo.pose.pose.orientation
        yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        dyaw = math.atan2(math.sin(yaw - th), math.cos(yaw - th))
        if not (same(p.x, bx, 1e-12) and same(p.y, by, 1e-12) and p.z == 0 and abs(dyaw) < 1e-12):
            fail(f"row {checked}: /odom pose {p.x},{p.y},{yaw} != axle {bx},{by},{th}")
        tw = odo.twist.twist
        if tw.linear.x != row["v_mps"] or tw.angular.z != row["omega_radps"] or tw.linear.y != 0:
            fail(f"row {checked}: /odom twist {tw.linear.x},{tw.angular.z}")
        tf = msgs["/tf"][i][1].transforms[0]
        tt = tf.transform.translation
        if (tf.header.frame_id, tf.child_frame_id) != ("odom", "base_link") or (tt.x, tt.y) != (p.x, p.y):
            fail(f"row {checked}: /tf differs from /odom")
        js = msgs["/joint_states"][i][1]
        if list(js.name) != ["right_wheel_joint", "left_wheel_joint"]:
            fail(f"joint names {js.name}")
        v, w = row["v_mps"], row["omega_radps"]
        want = [(v + h * w) / r, (v - h * w) / r]
        if not all(same(a, b, 1e-12) for a, b in zip(js.velocity, want)):
            fail(f"row {checked}: wheel rates {list(js.velocity)} != {want}")
        if list(js.effort) != [row["tau_r_nm"], row["tau_l_nm"]]:
            fail(f"row {checked}: efforts {list(js.effort)}")
        checked += 1
    # /diagnostics: the health of the tracking sample written with it.
    by_time = {t: m for t, m in msgs["/wmr/tracking"]}
    names = {0: "nominal", 1: "degraded", 2: "safe stop"}
    for t, dm in msgs["/diagnostics"]:
        st = dm.status[0]
        vals = {kv.key: kv.value for kv in st.values}
        tr = by_time.get(t)
        if tr is None:
            fail(f"/diagnostics at {t} has no tracking sample")
        if vals.get("health") != names.get(tr.health):
            fail(f"/diagnostics health {vals.get('health')} != tracking {tr.health}")
        want_level = 2 if (tr.state == 3 or tr.health >= 2) else (1 if (tr.health == 1 or tr.input_fault) else 0)
        if st.level != want_level:
            fail(f"/diagnostics level {st.level}, expected {want_level}")
    span = (msgs["/wmr/tracking"][-1][0] - msgs["/wmr/tracking"][0][0]) * 1e-9
    print(
        f"mcap_check: OK: {count} messages decoded and re-encoded byte for byte by rosbags; "
        f"{checked} rows equal the CSV; {len(msgs['/diagnostics'])} diagnostics over {span:.2f} s "
        f"({mcap_path})"
    )


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1], sys.argv[2])
