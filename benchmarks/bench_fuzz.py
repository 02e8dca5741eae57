"""A million fuzzed datagrams at one SITL vehicle (issue 12): does it keep answering, and does
its memory stay flat? The vehicle runs in this process (kinematic airframe); the fuzzer sends
from a child process, so the RSS measured is the vehicle's.

    nice -n 10 python benchmarks/bench_fuzz.py --datagrams 1000000

Prints datagrams sent, received, dropped as malformed, commands handled, handler errors, RSS
at start/end (goal: +< 5 MB) and whether a COMMAND_ACK came back after every 100k."""

from __future__ import annotations

import argparse
import multiprocessing as mp
import socket
import time
from pathlib import Path

from provenance import atomic_write_json, stamp
from sim.mavlink import Sitl, SitlConfig
from sim.mavlink.fuzz import send_fuzz


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def _port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _answers(port: int, sysid: int) -> bool:
    from pymavlink.dialects.v20 import common as m

    mav = m.MAVLink(None, srcSystem=250, srcComponent=190)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(0.3)
        parser = m.MAVLink(None)
        for _ in range(10):
            s.sendto(mav.command_long_encode(sysid, 1, m.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0).pack(mav),
                     ("127.0.0.1", port))
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                try:
                    data = s.recv(4096)
                except TimeoutError:
                    break
                try:
                    msgs = parser.parse_buffer(data) or []
                except m.MAVError:
                    continue
                if any(x.get_type() == "COMMAND_ACK" and x.command == m.MAV_CMD_REQUEST_MESSAGE for x in msgs):
                    return True
    return False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--datagrams", type=int, default=1_000_000)
    ap.add_argument("--chunk", type=int, default=100_000)
    ap.add_argument("--out", type=Path, default=Path("results/fuzz.json"))
    a = ap.parse_args()
    cfg = SitlConfig(instance=33, speedup=1.0, physics="kinematic", gcs_link=True, api_local_port=_port(),
                     api_remote_port=_port(), gcs_local_port=_port(), gcs_remote_port=_port())
    sitl = Sitl(cfg).start()
    time.sleep(2.0)
    rss0, t0, rows = _rss_mb(), time.monotonic(), []
    sent = 0
    ctx = mp.get_context("spawn")
    for k in range(0, a.datagrams, a.chunk):
        n = min(a.chunk, a.datagrams - k)
        p = ctx.Process(target=send_fuzz, args=(cfg.gcs_ports[0], n, k, cfg.sysid), kwargs={"per_sender": 50})
        p.start()
        p.join()
        sent += n
        v, stats = sitl.vehicle, sitl.vehicle.links[1].stats
        row = {"sent": sent, "received": stats.received, "bad_data": stats.bad_data, "commands": v.counters.commands,
               "handler_errors": len(v.counters.handler_errors), "peers": len(v.links[1].peers),
               "rss_mb": round(_rss_mb(), 1), "answers": _answers(cfg.gcs_ports[0], cfg.sysid),
               "wall_s": round(time.monotonic() - t0, 1)}
        rows.append(row)
        print(row, flush=True)
    sitl.stop()
    rss1 = rows[-1]["rss_mb"]
    summary = {"datagrams": sent, "rss_start_mb": round(rss0, 1), "rss_end_mb": rss1, "rss_growth_mb": round(rss1 - rss0, 1),
               "answered_after_every_chunk": all(r["answers"] for r in rows),
               "handler_errors": rows[-1]["handler_errors"], "sitl_errors": len(sitl.errors)}
    print(summary)
    atomic_write_json(a.out, stamp({"datagrams": a.datagrams, "chunk": a.chunk}, 0, kind="fuzz run", summary=summary,
                                   rows=rows))


if __name__ == "__main__":
    main()
