#!/usr/bin/env python3
"""The tap and the report of scripts/bench_ground.sh (mgmot ground -> FreeTAKServer -> pytak).

  bench_ground_report.py tap --port 8087 --out SENT_TAP.jsonl [--ready FILE]
      Records every TCP segment sent to PORT on the loopback interface (a packet socket with
      a BPF filter, as tcpdump would; root in the bench's network namespace), with the
      kernel's receive time, until SIGTERM / SIGINT. Passive: mgmot ground still connects
      straight to the server. One JSON object per segment: {"t", "src", "seq", "flags",
      "data" (base64)}.

  bench_ground_report.py report OUT_DIR [--json OUT]
      OUT_DIR holds received.jsonl (bench_tak_client.py), sent_tap.jsonl (the tap),
      ground_stats.json (mgmot ground --stats-json) and run1_stats.json, run2_stats.json
      (the two mgmot runs). Compares the fused events the ground sent (its counters, and the
      events the tap saw on its connection, the identity excluded) with the events of uid
      mgmot.ground.* the client received through the server, keyed by (uid, time) (plus the
      ended uid for a t-x-d-d delete, whose uid is the ground's); latency from each event's
      `time` to its arrival at the client (and the split: ground -> wire, wire -> client);
      checks every received event with cot_check.py. Exits 1 when drones != 2, an event is
      lost, p95 > 1 s, an event fails the schema, no fused track was received, or a drone's
      mgmot run saw another system's autopilot telemetry.
"""
import argparse
import base64
import bisect
import ctypes
import json
import re
import signal
import socket
import struct
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cot_check  # noqa: E402
from bench_tak_report import percentile  # noqa: E402

UID_PREFIX = "mgmot.ground."


# --- tap -----------------------------------------------------------------------------------

def bpf_tcp_port(port: int) -> bytes:
    """Classic BPF for `ip and tcp and (src port PORT or dst port PORT)` on an Ethernet-framed
    link (the loopback has a zeroed Ethernet header), first fragments only."""
    def ins(code, jt, jf, k):
        return struct.pack("HBBI", code, jt, jf, k)
    return b"".join([
        ins(0x28, 0, 0, 12),        # 0 ldh [12]           ethertype
        ins(0x15, 0, 9, 0x0800),    # 1 jeq IPv4 ? 2 : 11
        ins(0x30, 0, 0, 23),        # 2 ldb [23]           protocol
        ins(0x15, 0, 7, 6),         # 3 jeq TCP ? 4 : 11
        ins(0x28, 0, 0, 20),        # 4 ldh [20]           fragment offset
        ins(0x45, 5, 0, 0x1FFF),    # 5 jset ? 11 : 6
        ins(0xB1, 0, 0, 14),        # 6 ldxb 4*([14]&0xf)  IP header length
        ins(0x48, 0, 0, 14),        # 7 ldh [x+14]         source port
        ins(0x15, 3, 0, port),      # 8 jeq PORT ? 12 : 9
        ins(0x48, 0, 0, 16),        # 9 ldh [x+16]         destination port
        ins(0x15, 1, 0, port),      # 10 jeq PORT ? 12 : 11
        ins(0x06, 0, 0, 0),         # 11 ret 0
        ins(0x06, 0, 0, 262144),    # 12 ret all
    ])


def tap(port: int, out_path: str, ready: str):
    eth_p_all = 0x0003
    s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(eth_p_all))
    prog = bpf_tcp_port(port)
    buf = ctypes.create_string_buffer(prog)
    fprog = struct.pack("HL", len(prog) // 8, ctypes.addressof(buf))
    s.setsockopt(socket.SOL_SOCKET, 26, fprog)  # SO_ATTACH_FILTER
    try:
        s.setsockopt(socket.SOL_SOCKET, 33, 32 << 20)  # SO_RCVBUFFORCE (CAP_NET_ADMIN)
    except OSError:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 32 << 20)
    s.setsockopt(socket.SOL_SOCKET, 35, 1)  # SO_TIMESTAMPNS
    s.bind(("lo", 0))
    s.settimeout(0.5)
    stop = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.append(1))
    if ready:
        Path(ready).write_text("ready\n")
    n = 0
    with open(out_path, "w") as out:
        while not stop:
            try:
                pkt, anc, _, addr = s.recvmsg(262144, 64)
            except socket.timeout:
                out.flush()
                continue
            except InterruptedError:
                continue
            # The loopback shows every packet twice: as sent (PACKET_OUTGOING) and as received.
            if addr[2] == socket.PACKET_OUTGOING:
                continue
            t = time.time()
            for level, kind, data in anc:
                if level == socket.SOL_SOCKET and kind == 35 and len(data) >= 16:
                    sec, nsec = struct.unpack("qq", data[:16])
                    t = sec + nsec / 1e9
            ip = pkt[14:]
            ihl = (ip[0] & 0x0F) * 4
            total = struct.unpack("!H", ip[2:4])[0]
            tcp = ip[ihl:total]
            sport, dport, seq = struct.unpack("!HHI", tcp[:8])
            doff = (tcp[12] >> 4) * 4
            flags = tcp[13]
            data = tcp[doff:]
            if dport != port or not (data or flags & 0x03):  # payload, SYN or FIN
                continue
            src = f"{socket.inet_ntoa(ip[12:16])}:{sport}"
            out.write(json.dumps({"t": t, "src": src, "seq": seq, "flags": flags,
                                  "data": base64.b64encode(data).decode()}) + "\n")
            n += 1
    print(f"bench_ground tap: {n} segments to port {port}")


# --- report --------------------------------------------------------------------------------

def streams(tap_path: Path):
    """Each connection's byte stream (reassembled from the tap's segments, retransmissions
    and the loopback's duplicates dropped), with the time each part arrived; and the bytes
    missing from the capture."""
    by_src = {}
    for line in tap_path.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            by_src.setdefault(r["src"], []).append(r)
    out = {}
    for src, segs in by_src.items():
        syn = [r for r in segs if r["flags"] & 0x02]
        isn = (syn[0]["seq"] + 1) if syn else min(r["seq"] for r in segs)
        parts = {}
        for r in segs:
            data = base64.b64decode(r["data"])
            if not data:
                continue
            off = (r["seq"] - isn) % (1 << 32)
            prev = parts.get(off)
            if prev is None:
                parts[off] = (r["t"], data)
            else:  # a retransmission: the first time, the longest data
                parts[off] = (min(prev[0], r["t"]), data if len(data) > len(prev[1]) else prev[1])
        stream, times, holes, pos = bytearray(), [], 0, 0
        for off in sorted(parts):
            t, data = parts[off]
            if off + len(data) <= pos:
                continue
            if off > pos:
                holes += off - pos
                stream += b"\0" * (off - pos)
                pos = off
            new = data[pos - off:]
            times.append((pos, pos + len(new), t))
            stream += new
            pos += len(new)
        out[src] = (bytes(stream), times, holes)
    return out


def split(stream: bytes):
    """(start, end) of each `<event ...>...</event>` in a stream."""
    spans, pos = [], 0
    while True:
        end = stream.find(b"</event>", pos)
        if end < 0:
            return spans
        end += len(b"</event>")
        start = stream.rfind(b"<event", pos, end)
        spans.append((max(start, pos), end))
        pos = end


def parse(xml: str):
    """uid, time (unix s), type and the key of an event (None for what is not XML)."""
    from lxml import etree
    try:
        root = etree.fromstring(xml.encode())
    except etree.XMLSyntaxError:
        return None
    a = root.attrib
    uid, t, kind = a.get("uid", ""), a.get("time", ""), a.get("type", "")
    link = ""
    if kind == "t-x-d-d":
        lk = root.find("detail/link")
        link = lk.get("uid", "") if lk is not None else ""
    try:
        unix = cot_check.parse_time(t).timestamp()
    except ValueError:
        unix = float("nan")
    return {"uid": uid, "time": t, "unix": unix, "type": kind, "key": (uid, t, link)}


def lat(values):
    return {"n": len(values), "p50": percentile(values, 50), "p95": percentile(values, 95),
            "max": max(values) if values else float("nan")}


def report(out_dir: Path, json_out):
    ground = json.loads((out_dir / "ground_stats.json").read_text())
    cot = ground.get("cot") or {}
    runs = []
    for k in (1, 2):
        p = out_dir / f"run{k}_stats.json"
        runs.append(json.loads(p.read_text()) if p.exists() else {})

    # What the ground sent: its connections to the server as the tap saw them. The first
    # event of each is its identity (the server keeps it, as the client's name).
    sent, wire_time, holes, connections = {}, {}, 0, 0
    tap_path = out_dir / "sent_tap.jsonl"
    for src, (stream, times, h) in (streams(tap_path).items() if tap_path.exists() else []):
        spans = split(stream)
        events = [(s, e, stream[s:e].decode("utf-8", "replace")) for s, e in spans]
        first = parse(events[0][2]) if events else None
        if not first or not first["uid"].startswith(UID_PREFIX):
            continue  # another client (the pytak client's self-report)
        connections += 1
        holes += h
        ends = [b for _, b, _ in times]
        for s, e, xml in events[1:]:
            ev = parse(xml)
            if ev is None:
                continue
            i = bisect.bisect_left(ends, e)
            t = times[i][2] if i < len(times) else float("nan")
            sent[ev["key"]] = ev
            wire_time[ev["key"]] = t

    # What the client got through the server: the ground's events by their own uid (the
    # server also makes events that only link to it, e.g. a delete when a client leaves).
    rows = [json.loads(x) for x in (out_dir / "received.jsonl").read_text().splitlines() if x.strip()]
    ours = [r for r in rows if f'uid="{UID_PREFIX}' in r["xml"].split(">", 1)[0]]
    received, duplicates, end_to_end, server_hop, ground_hop = {}, 0, [], [], []
    track_events = 0
    for r in ours:
        ev = parse(r["xml"])
        if ev is None:
            continue
        if ev["key"] in received:
            duplicates += 1
            continue
        received[ev["key"]] = r["rx_unix_s"]
        # A fused track's event: uid mgmot.ground.<run tag>.<fused id>.
        if ev["type"] != "t-x-d-d" and re.fullmatch(r"mgmot\.ground\.[^.]+\.\d+", ev["uid"]):
            track_events += 1
        end_to_end.append(r["rx_unix_s"] - ev["unix"])
        if ev["key"] in wire_time:
            server_hop.append(r["rx_unix_s"] - wire_time[ev["key"]])
            ground_hop.append(wire_time[ev["key"]] - ev["unix"])
    check = cot_check.check([r["xml"] for r in ours])
    missing = sorted(k for k in sent if k not in received)
    extra = sorted(k for k in received if sent and k not in sent)
    types = check["types"]
    made = cot.get("queued", 0) + cot.get("dropped", 0)
    sent_n = cot.get("sent", 0)
    e2e = lat(end_to_end)
    result = {
        "ground": {
            "drones": ground.get("drones"),
            "track_messages": ground.get("ingest", {}).get("track_messages"),
            "track_reports_used": ground.get("ingest", {}).get("track_reports_used"),
            "fused_ids": ground.get("fused_ids"),
            "retired": ground.get("retired"),
            "updates": ground.get("updates"),
        },
        "cot": {
            "made": made,
            "sent": sent_n,
            "dropped": cot.get("dropped", 0),
            "unsent_at_exit": cot.get("unsent_at_exit", 0),
            "tap_events": len(sent),
            "tap_connections": connections,
            "tap_bytes_missing": holes,
            "received_by_client": len(received),
            "received_duplicates": duplicates,
            "lost": sent_n - len(received),
            "missing": [list(k) for k in missing[:50]],
            "missing_count": len(missing),
            "not_sent_by_ground": [list(k) for k in extra[:20]],
            "uids": check["uids"],
            "types": types,
            "track_events_received": track_events,
        },
        "latency_s": {
            "time_to_client": e2e,
            "time_to_wire": lat(ground_hop),
            "wire_to_client": lat(server_hop),
        },
        "schema_problems": check["problems"][:20],
        "schema_problem_count": len(check["problems"]),
        "drones": [
            {
                "system_id": k + 1,
                "frames_processed": r.get("frames_processed"),
                "frames_dropped": r.get("frames_dropped"),
                "track_messages": r.get("track_messages"),
                "telemetry_from_others": (r.get("link") or {}).get("telemetry_from_others"),
                "from_other_peers": (r.get("link") or {}).get("from_other_peers"),
                "frames_received": (r.get("link") or {}).get("frames_received"),
            }
            for k, r in enumerate(runs)
        ],
    }
    failures = []
    if result["ground"]["drones"] != 2:
        failures.append(f"the ground heard {result['ground']['drones']} drones, not 2")
    if result["cot"]["lost"] != 0 or missing:
        failures.append(f"{result['cot']['lost']} events lost ({len(missing)} of the tapped ones missing)")
    if made != sent_n:
        failures.append(f"the ground made {made} events but sent {sent_n}")
    if not (e2e["p95"] <= 1.0):
        failures.append(f"latency p95 {e2e['p95']:.3f} s > 1 s")
    if check["problems"]:
        failures.append(f"{len(check['problems'])} schema problems")
    if not result["ground"]["fused_ids"] or track_events <= 0:
        failures.append("no fused track at all")
    for d in result["drones"]:
        if d["telemetry_from_others"] is None:
            failures.append(f"no stats of drone {d['system_id']}'s mgmot run")
        elif d["telemetry_from_others"] > 0:
            failures.append(f"drone {d['system_id']}'s mgmot run got {d['telemetry_from_others']} "
                            "telemetry messages from another system (routing)")
    warnings = []
    if sent and len(sent) != sent_n:
        warnings.append(f"the tap saw {len(sent)} events, the ground counted {sent_n} sent")
    if holes:
        warnings.append(f"the tap missed {holes} bytes of the ground's stream")
    result["failures"] = failures
    result["warnings"] = warnings
    result["pass"] = not failures
    if json_out:
        Path(json_out).write_text(json.dumps(result, indent=1))

    g, c = result["ground"], result["cot"]
    ms = lambda v: f"{v * 1000:.0f} ms"  # noqa: E731
    print(f"ground bench: {g['drones']} drones heard, {g['track_reports_used']} of "
          f"{g['track_messages']} MGMOT_TRACK used, {g['fused_ids']} fused ids "
          f"({g['retired']} merged away), {g['updates']} updates")
    for d in result["drones"]:
        print(f"  drone {d['system_id']}: {d['frames_processed']} frames, {d['track_messages']} "
              f"MGMOT_TRACK sent, telemetry from other systems {d['telemetry_from_others']}")
    print(f"  fused CoT: made {made}, sent {sent_n} (tap: {c['tap_events']} on "
          f"{c['tap_connections']} connection(s)); the client received {c['received_by_client']} "
          f"through FreeTAKServer: lost {c['lost']}" + (f", missing {missing[:3]}" if missing else ""))
    print(f"  {c['uids']} uids, types {types}")
    for name, v in result["latency_s"].items():
        if v["n"]:
            print(f"  latency {name.replace('_', ' ')}: p50 {ms(v['p50'])}, p95 {ms(v['p95'])}, "
                  f"max {ms(v['max'])} ({v['n']} events)")
    print(f"  schema: {len(check['problems'])} problems"
          + (f" (first: {check['problems'][0]})" if check["problems"] else ""))
    for w in warnings:
        print(f"  warning: {w}")
    print("  verdict: " + ("PASS" if not failures else "FAIL: " + "; ".join(failures)))
    return 0 if not failures else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("tap")
    t.add_argument("--port", type=int, default=8087)
    t.add_argument("--out", required=True)
    t.add_argument("--ready", default="")
    r = sub.add_parser("report")
    r.add_argument("out_dir")
    r.add_argument("--json")
    a = ap.parse_args()
    if a.cmd == "tap":
        tap(a.port, a.out, a.ready)
    else:
        sys.exit(report(Path(a.out_dir), a.json))


if __name__ == "__main__":
    main()
