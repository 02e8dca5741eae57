"""The search journal: the companion's whole search state, written after every decision, so
a companion that restarts (killed, crashed, power-cycled) goes on with the search it was
flying instead of starting over (`uavsearch run --resume DIR`, autopilot_bridge.resume).

What is in it: the GPS estimator's Gaussian sum, the probabilistic visitation map, the targets
found (where the autopilot read them and the cells they stand on), the registration flag, the
telemetry intake's fixes not fused yet and its counters, the search log so far, the service's
and the policy's random streams, the policy's own state (autopilot_bridge.snapshot: a belief,
a tour, a hidden state), the schedule's times, and the loop's place: the next decision's
index, the cell the vehicle was sent to for it and its simulated time t_k. Beside it the
vehicle's home and clock at the save, for the resume to check the vehicle against.

How it is written, so a kill -9 at any instant leaves a journal that loads: two files in the
run's directory, `journal.json` (human-readable: provenance, config, the loop's place, the
state's tree) and `journal-NNNNN.npz` (the state's arrays), each written to a temporary name,
fsynced and renamed (provenance.atomic_open). The arrays go first under a new name; then the
JSON, which names them and their SHA-256, replaces the old JSON; only then are older array
files removed. A kill anywhere leaves the old pair or the new one whole. No pickle: JSON and an
npz read with allow_pickle=False run nothing when loaded.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import time
from collections import deque
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from provenance import atomic_write_bytes, atomic_write_json, stamp

from .search_data import SearchLog
from .snapshot import Decoder, Encoder, SnapshotError, restore, snapshot

if TYPE_CHECKING:
    from .service import PolicyService

KIND = "uavsearch journal"
FORMAT = 1
JOURNAL = "journal.json"
#: journal statuses: a search under way (or stopped by a failure: resumable), and one that ran
#: to its end (nothing to resume)
SEARCHING, ENDED = "searching", "ended"


class JournalError(ValueError):
    """A journal that is missing, unreadable, or not this search's; the message names the file."""


@dataclass(frozen=True)
class LoopState:
    """Where the decision loop stands between two decisions."""

    move: int  # the next decision's index (the moves flown so far)
    cell: tuple[int, int]  # the cell the vehicle was sent to for it
    t_k: float  # its simulated time on the vehicle's clock when the journal was written


@dataclass(frozen=True)
class JournalDoc:
    """A journal's JSON, checked: what `uavsearch run --resume` reads before it connects."""

    path: Path
    meta: dict[str, Any]

    @property
    def loop(self) -> LoopState:
        lp = self.meta["loop"]
        return LoopState(int(lp["move"]), (int(lp["cell"][0]), int(lp["cell"][1])), float(lp["t_k"]))

    @property
    def status(self) -> str:
        return str(self.meta["status"])

    @property
    def config(self) -> dict[str, Any]:
        return self.meta["provenance"]["config"]

    @property
    def seed(self) -> int:
        return int(self.meta["provenance"]["seed"])

    @property
    def resumes(self) -> list[dict[str, Any]]:
        return list(self.meta.get("resumes", []))


def _spec_dict(service: PolicyService) -> dict[str, Any]:
    """The search's identity: what a journal must agree with to be this search's."""
    s = service.spec
    return {"grid": s.grid.to_dict(), "origin": [s.origin.lat_deg, s.origin.lon_deg, s.origin.alt_m],
            "altitude_m": s.altitude_m, "arrive_m": s.arrive_m, "max_moves": s.max_moves,
            "decision_period_s": s.decision_period_s, "visit_map": s.visit_map, "exact_above": s.exact_above,
            "register": s.register, "map_from_reading": s.map_from_reading, "field_edge": s.field_edge,
            "policy": service.policy.name, "policy_class": type(service.policy).__qualname__, "seed": service.seed,
            "estimator": asdict(service.estimator.cfg)}


def state_of(service: PolicyService) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The service's search state as (JSON tree, arrays)."""
    enc = Encoder()
    est, intake, found = service.estimator, service.intake, service.found
    with intake._fix_lock:
        fixes = [list(f) for f in intake._fixes]
    plain = {
        "service": {"rng": service.rng, "log": asdict(service.log),
                    "kept_frames": [list(f) for f in service.kept_frames],
                    "last_frame": None if service.last_frame is None else list(service.last_frame)},
        "estimator": {"logw": est._logw, "x": est._x, "p": est._p, "t": est._t, "bias_var": est._bias_var,
                      "rejected": est.rejected},
        "pmap": {k: getattr(service.pmap, k) for k in ("visited", "met", "current", "trail", "recovered")},
        "found": {"found_at": [list(f) for f in found._found_at], "found_cells": list(found._found_cells),
                  "told_cells": list(found._told_cells)},
        "registration": {"launch_registered": service.registration.launch_registered},
        "intake": {"last_gps_t": intake.last_gps_t, "fixes": fixes, "fixes_late": intake.fixes_late,
                   "input_waits_timed_out": intake.input_waits_timed_out, "sim_time_s": intake.sim_time_s,
                   "first_fix_t": intake.first_fix_t, "dropped_until": intake._dropped_until},
        "pilot": {"t_ref": service.pilot.t_ref, "t_offboard": service.pilot.t_offboard,
                  # the altitude level the next move flies (only with levels: older journals read the same)
                  **({"level": service.height.level} if service.height.levels > 1 else {})},
    }
    tree = {k: enc.encode(v, k) for k, v in plain.items()}
    tree["policy"], _ = snapshot(service.policy, "policy", enc)
    return tree, enc.arrays


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def save(directory: Path, service: PolicyService, loop: LoopState, config: Any = None,
         status: str = SEARCHING, resumes: list[dict[str, Any]] | None = None,
         outcome: dict[str, Any] | None = None) -> Path:
    """Write the journal of `service` standing at `loop` into directory (see the module's
    docstring for why it survives a kill at any instant). Returns the JSON's path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    tree, arrays = state_of(service)
    data = _npz_bytes(arrays)
    name = f"journal-{loop.move:05d}.npz"
    atomic_write_bytes(directory / name, data)
    tel = service.link.telemetry
    meta = {
        "kind": KIND, "format": FORMAT, "status": status,
        "loop": {"move": loop.move, "cell": [int(loop.cell[0]), int(loop.cell[1])], "t_k": float(loop.t_k)},
        "search": _spec_dict(service),
        "vehicle": {"home": dict(tel.home), "sim_time_s": service.intake.sim_time_s,
                    "setpoint_local": service.log.setpoints_local[-1] if service.log.setpoints_local else None},
        "moves": loop.move,
        "found": len(service.log.believed_found),
        "resumes": list(resumes or []), "outcome": outcome, "saved_unix_s": time.time(),
        "arrays": {"file": name, "sha256": hashlib.sha256(data).hexdigest()},
        "provenance": stamp(config, service.seed, kind="search journal"),
        "state": tree,
    }
    path = directory / JOURNAL
    atomic_write_json(path, meta)
    for old in directory.glob("journal-*.npz"):
        if old.name != name:
            old.unlink(missing_ok=True)
    return path


def read(directory: Path) -> JournalDoc:
    """The journal's JSON in directory, checked to be a whole journal of this format, its
    arrays present with the SHA-256 it names. Every problem names the file."""
    path = Path(directory) / JOURNAL
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise JournalError(f"{path} does not exist: no search journal in {directory} (a search writes it "
                           "into its --out directory from its first decision on)") from None
    except OSError as e:
        raise JournalError(f"{path} cannot be read ({e})") from None
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as e:
        raise JournalError(f"{path} is not readable JSON ({e}): corrupt") from None
    if not isinstance(meta, dict) or meta.get("kind") != KIND:
        raise JournalError(f"{path} is not a uavsearch search journal "
                           f"(kind {meta.get('kind') if isinstance(meta, dict) else None!r})")
    if meta.get("format") != FORMAT:
        raise JournalError(f"{path} is journal format {meta.get('format')!r}; this uavsearch reads format {FORMAT}")
    for key in ("status", "loop", "search", "vehicle", "arrays", "provenance", "state"):
        if key not in meta:
            raise JournalError(f"{path} has no {key!r}: corrupt or from another version")
    doc = JournalDoc(path, meta)
    try:
        doc.loop  # noqa: B018 - checks it parses
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise JournalError(f"{path}: bad 'loop' entry ({type(e).__name__}: {e})") from None
    return doc


def _arrays(doc: JournalDoc) -> dict[str, np.ndarray]:
    a = doc.meta["arrays"]
    path = doc.path.parent / str(a.get("file"))
    try:
        data = path.read_bytes()
    except OSError as e:
        raise JournalError(f"{path} (the arrays {doc.path} names) cannot be read ({e})") from None
    if hashlib.sha256(data).hexdigest() != a.get("sha256"):
        raise JournalError(f"{path} is not the file {doc.path} was written with (SHA-256 differs): corrupt")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise JournalError(f"{path} is not a readable npz ({e})") from None


def check_fits(doc: JournalDoc, service: PolicyService) -> None:
    """The journal is this search's (field, policy, seed, search settings), or an error naming
    the file and the first setting that differs."""
    mine, theirs = _spec_dict(service), doc.meta["search"]
    for key, value in mine.items():
        if theirs.get(key) != value:
            raise JournalError(f"{doc.path} is the journal of another search: its {key} is {theirs.get(key)!r}, "
                               f"this one's {value!r}")


def load(directory: Path, service: PolicyService) -> LoopState:
    """Restore `service` (fresh: built for the same field, policy and seed, its link up) to the
    journal's state exactly, and return where its decision loop stands. The policy is reset for
    the field and seed, then its journaled state laid over it (autopilot_bridge.snapshot)."""
    doc = read(directory)
    check_fits(doc, service)
    arrays = _arrays(doc)
    tree = doc.meta["state"]
    try:
        _restore(service, tree, arrays)
    except (SnapshotError, KeyError, TypeError, ValueError) as e:
        raise JournalError(f"{doc.path}: its state does not fit this service ({type(e).__name__}: {e})") from None
    return doc.loop


def _restore(service: PolicyService, tree: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
    dec = Decoder(arrays)
    part = {k: dec.decode(v, None, k) for k, v in tree.items() if k != "policy"}
    sv = part["service"]
    service.rng = sv["rng"]
    saved = SearchLog(**sv["log"])  # a field missing or unknown is another version's journal
    saved.cells = [tuple(c) for c in saved.cells]
    for f in fields(SearchLog):  # in place: the parts that write the log (the pilot) hold it too
        setattr(service.log, f.name, getattr(saved, f.name))
    service.kept_frames = [tuple(f) for f in sv["kept_frames"]]
    service.last_frame = None if sv["last_frame"] is None else tuple(sv["last_frame"])
    est, e = service.estimator, part["estimator"]
    est._logw, est._x, est._p = e["logw"], e["x"], e["p"]
    est._t, est._bias_var, est.rejected = e["t"], e["bias_var"], int(e["rejected"])
    for k, v in part["pmap"].items():
        setattr(service.pmap, k, v)
    f = part["found"]
    service.found._found_at = [(float(t), np.asarray(p)) for t, p in f["found_at"]]
    service.found._found_cells = [None if c is None else tuple(c) for c in f["found_cells"]]
    service.found._told_cells = [tuple(c) for c in f["told_cells"]]
    service.registration.launch_registered = bool(part["registration"]["launch_registered"])
    i, intake = part["intake"], service.intake
    with intake._fix_lock:  # the link may have queued fixes since it came up: the journal's go first
        saved = [(float(t), np.asarray(n), float(h), float(v)) for t, n, h, v in i["fixes"]]
        last = saved[-1][0] if saved else -math.inf
        intake._fixes = deque(saved + [x for x in intake._fixes if x[0] > last + 1e-9])
        intake.last_gps_t = max(float(i["last_gps_t"]), intake.last_gps_t)
        if intake.first_fix_t is None or i["first_fix_t"] is not None:
            intake.first_fix_t = i["first_fix_t"]
    intake.fixes_late = int(i["fixes_late"])
    intake.input_waits_timed_out = int(i["input_waits_timed_out"])
    intake.sim_time_s = max(float(i["sim_time_s"]), intake.sim_time_s)
    intake._dropped_until = float(i["dropped_until"])
    service.pilot.t_ref, service.pilot.t_offboard = part["pilot"]["t_ref"], part["pilot"]["t_offboard"]
    if service.height.levels > 1:  # the rejoin flies its height (resume._hand_over)
        service.height.set_level(int(part["pilot"].get("level", 1)))
    service.policy.reset(service.spec.grid, 1, service.seed)
    restore(service.policy, tree["policy"], arrays, "policy")


class Journal:
    """The decision loop's hook (`PolicyService.journal`): the journal written after every
    decision into `directory`, with the run's config for provenance and the resumes so far."""

    def __init__(self, directory: Path, service: PolicyService, config: Any = None,
                 resumes: list[dict[str, Any]] | None = None) -> None:
        self.directory, self.service, self.config = Path(directory), service, config
        self.resumes = list(resumes or [])
        self.last: LoopState | None = None
        self.writes = 0
        self.write_s = 0.0  # wall seconds spent writing (the decision loop waits for it)

    def __call__(self, move: int, cell: np.ndarray, t_k: float) -> None:
        t0 = time.perf_counter()
        self.last = LoopState(int(move), (int(cell[0]), int(cell[1])), float(t_k))
        save(self.directory, self.service, self.last, self.config, SEARCHING, self.resumes)
        self.writes += 1
        self.write_s += time.perf_counter() - t0

    def end(self, outcome: dict[str, Any], ended: bool) -> None:
        """After the flight: `ended` (the search ran to its end, nothing to resume) or not (it
        stopped on a failure or a signal: resumable), with how it ended."""
        if self.last is None:
            return  # never got to a decision: nothing to resume, nothing written
        mark(self.directory, ENDED if ended else SEARCHING, outcome)


def mark(directory: Path, status: str, outcome: dict[str, Any] | None) -> None:
    """Set the journal's status and outcome, its state as the last decision left it (the
    service has moved on since, part way into a decision the journal does not hold)."""
    doc = read(directory)
    atomic_write_json(doc.path, {**doc.meta, "status": status, "outcome": outcome})
