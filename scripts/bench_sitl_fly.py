#!/usr/bin/env python3
"""The ground station of the SITL bench (scripts/bench_sitl.sh): flies ArduCopter SITL and taps
what reaches the ground in both topologies.

- Radio tap: a TCP connection to SITL's SERIAL0 (the telemetry radio). It flies the vehicle
  (GUIDED, arm, take off, a there-and-back search leg over the scenario's objects, gimbal sweeps
  with DO_MOUNT_CONTROL), selects a track with MAV_CMD_CAMERA_TRACK_POINT sent to mgmot through
  the autopilot, asks for SIMSTATE (SITL's true state), and records everything it receives.
- Router tap: a UDP port the companion router (mavlink-router) sends to: a ground station with a
  direct path to mgmot. It only listens.

Both are decoded with mgmot's dialect (firmware-config/mavlink/mgmot.xml: common + ardupilotmega
+ MGMOT_TRACK) and written as tlogs (8-byte big-endian UNIX microseconds + the raw packet). A
JSON summary goes to --out.

--reboot-at S reboots the autopilot S seconds after the start (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN,
param1 1). ArduPilot refuses to reboot while armed unless forced (COMMAND_INT y = 20190226): by
default the bench forces it in the air, as a watchdog or brown-out would; --reboot-landed lands
and disarms first. SITL re-execs itself (and closes its TCP ports): the radio tap reconnects to
SERIAL0, waits for the autopilot's HEARTBEAT, asks for its streams again and flies the whole
pattern again (take-off, search leg, sweeps), so the objects are seen before and after the
reboot. The times (UNIX, companion clock) go to the summary's "reboot". --reboot-dry-run is the
control for it: at S it lands and disarms, skips the reboot and flies the pattern again.

Usage: bench_sitl_fly.py --sitl-port 5760 --router-port 14550 --out DIR [--leg-m 200]
                         [--system-id 1] [--altitude-m 30] [--east-m 0]
                         [--reboot-at S [--reboot-landed | --reboot-dry-run]]
"""
import argparse
import json
import math
import os
import select
import socket
import struct
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from runtime_mavlink_tap import load_dialect  # noqa: E402

GCS = (255, 190)
# The vehicle's system id (--system-id): the autopilot is (SYSID, 1), mgmot (SYSID, 191).
SYSID = 1
MGMOT = (SYSID, 191)
# ArduPilot reboots while armed only with this in COMMAND_INT.y (GCS_Common.cpp).
FORCE_REBOOT_MAGIC = 20190226


class RebootNow(Exception):
    """Raised by the pump when the time for the autopilot's reboot has come."""


class Tap:
    """One connection: parses, counts and records what arrives."""

    def __init__(self, dialect, name, sock, tlog_path, send=None):
        self.name, self.sock, self.send_raw = name, sock, send
        self.mav = dialect.MAVLink(self, srcSystem=GCS[0], srcComponent=GCS[1])
        self.mav.robust_parsing = True
        self.tlog = open(tlog_path, "wb")
        self.counts, self.first, self.last, self.by_sender = {}, {}, {}, {}
        self.messages = []

    def write(self, data):  # the MAVLink object's output
        if self.send_raw:
            self.send_raw(data)

    def restart_parser(self):
        """A new connection: drop the bytes of a packet the old one left half-parsed."""
        self.mav.buf = bytearray()
        self.mav.buf_index = 0
        self.mav.expected_length = self.mav.__class__(None).expected_length  # the start state
        self.mav.have_prefix_error = False

    def feed(self, data):
        now = time.time()
        for m in self.mav.parse_buffer(data) or []:
            t = m.get_type()
            if t == "BAD_DATA":
                continue
            self.tlog.write(struct.pack(">Q", int(now * 1e6)) + m.get_msgbuf())
            self.counts[t] = self.counts.get(t, 0) + 1
            self.first.setdefault(t, now)
            self.last[t] = now
            key = "%s %d/%d" % (t, m.get_srcSystem(), m.get_srcComponent())
            self.by_sender[key] = self.by_sender.get(key, 0) + 1
            self.messages.append((now, m))

    def rates(self, since):
        out = {}
        for t, n in sorted(self.counts.items()):
            recent = [x for x, m in self.messages if m.get_type() == t and x >= since]
            span = (recent[-1] - recent[0]) if len(recent) > 1 else 0.0
            out[t] = {"count": n, "rate_hz": round((len(recent) - 1) / span, 2) if span > 0 else None}
        return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sitl-port", type=int, default=5760)
    ap.add_argument("--router-port", type=int, default=14550)
    ap.add_argument("--out", required=True)
    ap.add_argument("--altitude-m", type=float, default=30.0)
    ap.add_argument("--leg-m", type=float, default=200.0, help="length of the search leg north of home")
    ap.add_argument("--speed-mps", type=float, default=5.0)
    ap.add_argument("--east-m", type=float, default=0.0, help="the pattern's offset east of home")
    ap.add_argument("--system-id", type=int, default=1, help="the vehicle's MAVLink system id (SITL --sysid)")
    ap.add_argument("--reboot-at", type=float, default=None,
                    help="reboot the autopilot this many seconds after the start, then fly the pattern again")
    ap.add_argument("--reboot-landed", action="store_true",
                    help="land and disarm before the reboot (default: forced reboot in the air)")
    ap.add_argument("--reboot-dry-run", action="store_true",
                    help="at --reboot-at, land and disarm but do not reboot, then fly the pattern again (the control)")
    args = ap.parse_args()
    global SYSID, MGMOT
    SYSID, MGMOT = args.system_id, (args.system_id, 191)
    autopilot = (SYSID, 1)
    os.makedirs(args.out, exist_ok=True)
    dialect = load_dialect()

    def connect_radio(tries, wait=time.sleep):
        for _ in range(tries):
            try:
                return socket.create_connection(("127.0.0.1", args.sitl_port), timeout=2)
            except OSError:
                wait(0.2)
        return None

    radio_sock = connect_radio(300)
    if radio_sock is None:
        sys.exit("bench: SITL's SERIAL0 (tcp %d) did not open" % args.sitl_port)
    link = {"sock": radio_sock}

    def radio_send(data):
        if link["sock"] is not None:
            try:
                link["sock"].sendall(data)
            except OSError:
                pass  # the autopilot is rebooting: the pump notices the closed connection

    radio = Tap(dialect, "radio", radio_sock, os.path.join(args.out, "gcs_radio.tlog"), radio_send)
    router_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    router_sock.bind(("127.0.0.1", args.router_port))
    router = Tap(dialect, "router", router_sock, os.path.join(args.out, "gcs_router.tlog"))
    m = radio.mav
    # "epoch": the start of the autopilot's current boot as far as the radio knows (latest()
    # ignores what an earlier boot said).
    state = {"phase": "wait_gps", "t0": time.time(), "phase_t": time.time(), "events": [], "epoch": 0.0}
    reboot = {"at": args.reboot_at, "pending": args.reboot_at is not None, "info": None}

    def log(text):
        state["events"].append([round(time.time() - state["t0"], 1), text])
        print("bench: %5.1f s  %s" % (time.time() - state["t0"], text), flush=True)

    def pump(seconds):
        end = time.time() + seconds
        while time.time() < end:
            if reboot["pending"] and time.time() - state["t0"] >= reboot["at"]:
                reboot["pending"] = False
                raise RebootNow()
            socks = [router_sock] + ([link["sock"]] if link["sock"] is not None else [])
            r, _, _ = select.select(socks, [], [], max(0.0, min(0.1, end - time.time())))
            if link["sock"] is not None and link["sock"] in r:
                try:
                    data = link["sock"].recv(65536)
                except OSError:
                    data = b""
                if not data:
                    if reboot["info"] is None or reboot["info"].get("link_closed_at") is not None:
                        sys.exit("bench: SITL closed the radio connection")
                    reboot["info"]["link_closed_at"] = time.time()
                    link["sock"].close()
                    link["sock"] = None
                else:
                    radio.feed(data)
            if router_sock in r:
                router.feed(router_sock.recv(65536))

    def command(cmd, *params, target=None):
        target = target or autopilot
        p = list(params) + [0] * (7 - len(params))
        m.command_long_send(target[0], target[1], cmd, 0, *p)

    def latest(t, since=None):
        """The autopilot's latest message of type `t` (received after `since`, by default in
        its current boot)."""
        since = state["epoch"] if since is None else since
        for when, msg in reversed(radio.messages):
            if when < since:
                break
            if msg.get_type() == t and (msg.get_srcSystem(), msg.get_srcComponent()) == autopilot:
                return msg
        return None

    def goto(north_m, east_m):
        home = state["home"]
        lat = home[0] + north_m / 111320.0
        lon = home[1] + east_m / (111320.0 * math.cos(math.radians(home[0])))
        m.set_position_target_global_int_send(
            0, SYSID, 1, dialect.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0b0000111111111000,
            int(lat * 1e7), int(lon * 1e7), args.altitude_m, 0, 0, 0, 0, 0, 0, 0, 0)

    def gimbal(pitch_deg, yaw_deg):
        # DO_MOUNT_CONTROL: pitch, roll, yaw (deg), mode MAVLINK_TARGETING.
        command(dialect.MAV_CMD_DO_MOUNT_CONTROL, pitch_deg, 0, yaw_deg, 0, 0, 0, dialect.MAV_MOUNT_MODE_MAVLINK_TARGETING)

    def fly(flight):
        """Streams, GPS, arm, take-off and the search pattern; `flight` 1, or 2 after a reboot."""
        fly_start = time.time()
        # Streams for the ground station: position, attitude, SITL's true state, gimbal, home.
        pump(2)
        for msg_id, hz in [(33, 10), (30, 10), (164, 10), (285, 10), (242, 1), (24, 2), (253, 0)]:
            if hz:
                command(dialect.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)
            pump(0.2)
        # The bench does not calibrate sensors or set up an RC transmitter.
        m.param_set_send(SYSID, 1, b"ARMING_CHECK", 0, dialect.MAV_PARAM_TYPE_INT32)
        pump(1)
        log("waiting for a GPS fix and the EKF")
        while True:
            pump(1)
            gps = latest("GPS_RAW_INT")
            pos = latest("GLOBAL_POSITION_INT")
            if gps is not None and gps.fix_type >= 3 and pos is not None and pos.lat != 0 and time.time() - fly_start > 25:
                break
            if time.time() - fly_start > 180:
                sys.exit("bench: no GPS fix in 180 s")
        pos = latest("GLOBAL_POSITION_INT")
        # The pattern stays where flight 1 put it (a dry run lands away from home).
        state.setdefault("home", (pos.lat * 1e-7, pos.lon * 1e-7))
        log("flight %d: GPS fix at %.6f, %.6f; pattern from %.6f, %.6f" % ((flight, pos.lat * 1e-7, pos.lon * 1e-7) + state["home"]))
        m.set_mode_send(SYSID, dialect.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4)  # GUIDED
        pump(1)
        # Until the EKF has a position estimate the autopilot refuses ("Arm: Need Position
        # Estimate"): ask again until COMMAND_ACK says ACCEPTED.
        for attempt in range(60):
            asked = time.time()
            command(dialect.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            pump(1.5)
            ack = latest("COMMAND_ACK", asked)
            if ack is not None and ack.command == dialect.MAV_CMD_COMPONENT_ARM_DISARM and ack.result == 0:
                break
        else:
            sys.exit("bench: the vehicle did not arm")
        log("armed; taking off to %.0f m" % args.altitude_m)
        command(dialect.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, args.altitude_m)
        while (latest("GLOBAL_POSITION_INT").relative_alt / 1000.0) < args.altitude_m - 1.5:
            pump(0.5)
        gimbal(-60, 0)
        command(dialect.MAV_CMD_DO_CHANGE_SPEED, 1, args.speed_mps, -1)
        log("search leg north, gimbal -60 forward")
        goto(args.leg_m, args.east_m)
        leg_s = args.leg_m / args.speed_mps
        # The operator clicks on a track as soon as one shows: its box is taken from the router
        # tap's latest MGMOT_TRACK (as a ground station showing the video would), the command goes
        # through the radio, i.e. through the autopilot, which routes it to mgmot's component.
        selected = {"at": None}  # per flight: after a reboot the operator clicks again

        def try_select():
            if selected["at"] is not None:
                return
            tracks = [x for w, x in router.messages[-600:] if x.get_type() == "MGMOT_TRACK" and w > time.time() - 1.0]
            if not tracks:
                return
            t = tracks[-1]
            asked = time.time()
            command(dialect.MAV_CMD_CAMERA_TRACK_POINT, t.bbox_x + t.bbox_w / 2, t.bbox_y + t.bbox_h / 2, 0.02, target=MGMOT)
            pump(1.0)
            ack = [x for w, x in radio.messages if w >= asked and x.get_type() == "COMMAND_ACK"
                   and (x.get_srcSystem(), x.get_srcComponent()) == MGMOT]
            result = ack[-1].result if ack else None
            log("operator clicks on track #%d (MAV_CMD_CAMERA_TRACK_POINT via the radio): COMMAND_ACK %s" % (t.track_id, result))
            if result == 0:
                selected["at"] = time.time()

        leg_end = time.time() + leg_s + 5
        while time.time() < leg_end:
            try_select()
            pump(1.0)
        log("back south with gimbal sweeps")
        goto(0, args.east_m)
        back_start = time.time()
        k = 0
        while time.time() - back_start < leg_s + 5:
            gimbal(-50 - 10 * (k % 2), [-30, 0, 30, 0][k % 4])
            k += 1
            for _ in range(4):
                try_select()
                pump(1.0)

    def do_reboot():
        """Reboots the autopilot and waits for it to come back on the radio."""
        info = {"requested_at": None, "mode": "dry run (landed, no reboot)" if args.reboot_dry_run
                else "landed" if args.reboot_landed else "forced in the air"}
        pos = latest("GLOBAL_POSITION_INT")
        info["relative_alt_m"] = pos.relative_alt / 1000.0 if pos is not None else None
        hb = latest("HEARTBEAT")
        info["armed"] = bool(hb is not None and hb.base_mode & dialect.MAV_MODE_FLAG_SAFETY_ARMED)
        if (args.reboot_landed or args.reboot_dry_run) and info["armed"]:
            log("reboot: landing and disarming first")
            m.set_mode_send(SYSID, dialect.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 9)  # LAND
            deadline = time.time() + 120
            while time.time() < deadline:
                pump(1)
                hb = latest("HEARTBEAT", time.time() - 1.5)
                if hb is not None and not hb.base_mode & dialect.MAV_MODE_FLAG_SAFETY_ARMED:
                    break
            else:
                sys.exit("bench: the vehicle did not disarm after landing")
            info["armed"] = False
            info["relative_alt_m"] = latest("GLOBAL_POSITION_INT").relative_alt / 1000.0
        reboot["info"] = info
        info["requested_at"] = time.time()
        if args.reboot_dry_run:
            log("reboot dry run: no reboot; flying the pattern again")
            return
        log("reboot: MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN%s (armed %s, %.1f m above home)"
            % (", forced" if info["armed"] else "", info["armed"], info["relative_alt_m"] or 0.0))
        m.command_int_send(SYSID, 1, 0, dialect.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 0, 0, 1, 0, 0, 0,
                           0, FORCE_REBOOT_MAGIC if info["armed"] else 0, 0)
        deadline = time.time() + 10
        while link["sock"] is not None and time.time() < deadline:
            pump(0.1)
        acks = [x for w, x in radio.messages if w >= info["requested_at"] and x.get_type() == "COMMAND_ACK"
                and x.command == dialect.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN]
        info["ack"] = acks[-1].result if acks else None
        if link["sock"] is not None:
            sys.exit("bench: the autopilot did not reboot (COMMAND_ACK %s)" % info["ack"])
        log("reboot: COMMAND_ACK %s; SITL closed the radio connection %.2f s after the command"
            % (info["ack"], info["link_closed_at"] - info["requested_at"]))
        sock = connect_radio(300, wait=pump)  # the router tap keeps listening meanwhile
        if sock is None:
            sys.exit("bench: SITL's SERIAL0 did not open again after the reboot")
        info["reconnected_at"] = time.time()
        radio.restart_parser()
        link["sock"] = sock
        state["epoch"] = info["reconnected_at"]
        deadline = time.time() + 60
        while latest("HEARTBEAT") is None:
            if time.time() > deadline:
                sys.exit("bench: no HEARTBEAT from the autopilot within 60 s of the reboot")
            pump(0.1)
        info["heartbeat_at"] = next(w for w, x in radio.messages if w >= state["epoch"] and x.get_type() == "HEARTBEAT"
                                    and (x.get_srcSystem(), x.get_srcComponent()) == autopilot)
        log("reboot: radio reconnected %.2f s, autopilot HEARTBEAT %.2f s after the command"
            % (info["reconnected_at"] - info["requested_at"], info["heartbeat_at"] - info["requested_at"]))

    flight = 1
    while True:
        try:
            fly(flight)
            break
        except RebootNow:
            do_reboot()
            flight += 1
    command(dialect.MAV_CMD_CAMERA_STOP_TRACKING, target=MGMOT)
    log("landing")
    m.set_mode_send(SYSID, dialect.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 9)  # LAND
    pump(5)
    summary = {
        "events": state["events"],
        "home": state["home"],
        "t0": state["t0"],
        "reboot": reboot["info"],
        "radio": {"by_sender": radio.by_sender},
        "router": {"by_sender": router.by_sender},
    }
    with open(os.path.join(args.out, "gcs_summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    log("done")


if __name__ == "__main__":
    main()
