"""The lossy-link sweep (issue 12): full searches and mission uploads through the seeded fault
proxy, with the counts of what completed and what the radio did.

    nice -n 10 python benchmarks/bench_lossy_link.py --searches 10 --uploads 10

Goal: 10/10 searches at 20 % loss + 5 % duplication + 5 % reordering (0-5 ms jitter), 10/10
mission uploads at 20 % loss. Writes results/lossy_link.json with provenance."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from missions.lossy import fly_lossy_search, lossy_mission_upload
from provenance import atomic_write_json, stamp
from sim.mavlink.faultproxy import LinkFaults


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--searches", type=int, default=10)
    ap.add_argument("--uploads", type=int, default=10)
    ap.add_argument("--max-moves", type=int, default=None, help="cap per search (default: the grid's t_e)")
    ap.add_argument("--speedup", type=float, default=10.0)
    ap.add_argument("--out", type=Path, default=Path("results/lossy_link.json"))
    a = ap.parse_args()
    search_faults = LinkFaults(loss=0.2, duplicate=0.05, reorder=0.05, delay_ms=(0.0, 5.0), reorder_ms=20)
    upload_faults = LinkFaults(loss=0.2)
    uploads, searches = [], []
    for seed in range(a.uploads):
        r = lossy_mission_upload(upload_faults, seed)
        uploads.append(r)
        print(f"upload seed {seed}: {'ok' if r['ok'] else 'FAILED'} in {r['wall_s']:.1f} s "
              f"(lost {r['up']['lost']} up, {r['down']['lost']} down)", flush=True)
    for seed in range(a.searches):
        t0 = time.monotonic()
        r = fly_lossy_search(search_faults, seed=seed, max_moves=a.max_moves, speedup=a.speedup)
        searches.append(r)
        print(f"search seed {seed}: {'ok' if r['error'] is None else 'FAILED: ' + r['error']} - {r['moves']} moves, "
              f"{r['frames']} frames, {r['link']['command_retries']} command resends, lost {r['up']['lost']} up / "
              f"{r['down']['lost']} down of {r['up']['forwarded']} / {r['down']['forwarded']}, "
              f"{time.monotonic() - t0:.0f} s", flush=True)
    ok_u = sum(r["ok"] for r in uploads)
    ok_s = sum(r["error"] is None and not r["armed_at_end"] for r in searches)
    print(f"mission uploads at 20 % loss: {ok_u}/{len(uploads)}")
    print(f"searches at 20 % loss + 5 % dup + 5 % reorder: {ok_s}/{len(searches)}")
    atomic_write_json(a.out, stamp({"search_faults": search_faults.__dict__, "upload_faults": upload_faults.__dict__,
                                    "speedup": a.speedup, "max_moves": a.max_moves}, 0, kind="lossy link sweep",
                                   uploads_ok=ok_u, uploads=uploads, searches_ok=ok_s, searches=searches))
    print(json.dumps({"uploads_ok": ok_u, "searches_ok": ok_s}))


if __name__ == "__main__":
    main()
