"""An example supervisor: plain Zenoh + MessagePack, as a client in another language would.

It imports nothing from this project: the messages are MessagePack maps whose fields are
described in ``schemas/supervisor.schema.json`` (JSON Schema; SI units, so openings and
positions in metres). It

1. checks the services' liveliness tokens (``<prefix>/alive/*``),
2. submits a task (``<prefix>/sequencer/submit``, a Zenoh get with the Task as payload;
   the reply is a SubmitReply: a task id, or every validation error); when the task
   cannot be planned from where the arm is (a folded arm, as after power-up) but can be
   after the arm's own fold-out, it unfolds the arm first (``--no-fold-out``: never),
3. prints the task's events (``<prefix>/sequencer/events``) until it ends, and can
   pause it after a while and resume it (``<prefix>/sequencer/control``),
4. watches the sequencer's liveliness token (``<prefix>/alive/sequencer``): when it
   vanishes while this client is still linked to its router, the sequencer died or hangs
   and no final event may come, so it stops waiting; when it vanished with this client's
   own link (a router restart), it waits for the token to come back and reads the task's
   record in ``<prefix>/sequencer/history``: the final event published while the link
   was down is there (``final``), exactly as published (docs/architecture.md, Learning
   how a task ended);
5. with ``--scene FILE``, first replaces the scene every plan is checked against
   (``<prefix>/planner/scene``: a SceneUpdate with the file's YAML text; the reply is a
   SceneReply: the new version, or the error naming line and field).

    python examples/supervisor.py --connect tcp/127.0.0.1:7447 paths/thesis_square.txt 40
    python examples/supervisor.py --pause-after 3 --resume-after 2 paths/thesis_square.txt

Exit status: 0 when the task succeeded, 1 when it failed or was cancelled or the
sequencer vanished (named), 2 when it was refused. Via-point files are read here (14
columns in mm, deg, s; docs/protocol.md, Thesis via-point format) and sent in SI units.
"""

from __future__ import annotations

import argparse
import json
import math
import queue
import sys
import time
from typing import Any

import msgpack
import zenoh

MM, DEG = 1e-3, math.pi / 180.0


def via_points(file: str) -> list[dict[str, Any]]:
    """A via-point file as a list of ViaPoint maps (SI units)."""
    out = []
    with open(file, encoding="utf-8") as f:
        for number, line in enumerate(f, start=1):
            cols = line.split("#", 1)[0].split()
            if not cols:
                continue
            v = [float(c) for c in cols]
            out.append({
                "xyz": [v[0] * MM, v[1] * MM, v[2] * MM],
                "velocity": [v[3] * MM, v[4] * MM, v[5] * MM],
                # file order yaw, roll, pitch -> message order yaw, pitch, roll
                "ypr": [v[6] * DEG, v[8] * DEG, v[7] * DEG],
                "angular_velocity": [v[9] * DEG, v[11] * DEG, v[10] * DEG],
                "time": v[12], "type": int(v[13]), "line": number,
            })  # fmt: skip
    return out


def task_from_words(words: list[str]) -> dict[str, Any]:
    """The thesis form (files and openings in mm, alternating) as a Task map."""
    steps: list[dict[str, Any]] = []
    for word in words:
        try:
            opening_mm = float(word)
        except ValueError:
            path = {"via_points": via_points(word), "source": word}
            steps.append({"kind": "move", "path": path, "where": word})
        else:
            steps.append({"kind": "gripper", "opening": opening_mm * MM, "where": word})
    return {"steps": steps, "name": "supervisor example: " + " ".join(words)}


def parse_args() -> argparse.Namespace:
    """The command line (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("task", nargs="+", help="via-point files and openings [mm]")
    parser.add_argument("--connect", default="tcp/127.0.0.1:7447", help="router endpoint")
    parser.add_argument("--prefix", default="manus", help="key prefix of the arm")
    parser.add_argument("--pause-after", type=float, default=None, metavar="S",
                        help="pause the task this long after it starts [s]")  # fmt: skip
    parser.add_argument("--resume-after", type=float, default=1.0, metavar="S",
                        help="resume this long after the pause [s]")  # fmt: skip
    parser.add_argument("--timeout", type=float, default=300.0, help="give up after [s]")
    parser.add_argument("--scene", metavar="FILE", help="replace the scene first (YAML)")
    parser.add_argument("--no-fold-out", action="store_true",
                        help="never unfold the arm first (a task that cannot be planned "
                             "from where the arm is is refused)")  # fmt: skip
    return parser.parse_args()


def open_session(endpoint: str) -> zenoh.Session:
    """A client of the router at ``endpoint``, loopback only: no scouting."""
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


GONE: dict[str, Any] = {"event": "sequencer_gone"}
"""Put in the event queue when the sequencer's liveliness token vanishes."""
BACK: dict[str, Any] = {"event": "sequencer_back"}
"""Put in the event queue when the sequencer's liveliness token appears again."""
LINK_SETTLE_S, LINK_WAIT_S, RECHECK_S = 0.25, 30.0, 1.0
"""After the token vanished: how long to look whether our own link went down with it;
how long to wait for link and token to come back; then how often to read the task's
record until it has ended [s]."""


def link_up(session: zenoh.Session) -> bool:
    """Whether the session is linked to a router (or a peer) now."""
    return bool(session.info.routers_zid() or session.info.peers_zid())


class Sequencer:
    """The sequencer's API under ``prefix``: liveliness, queries, and its task events."""

    def __init__(self, session: zenoh.Session, prefix: str) -> None:
        self.session = session
        self.prefix = prefix
        self.events: queue.Queue[dict[str, Any]] = queue.Queue()
        session.declare_subscriber(
            f"{prefix}/sequencer/events",
            lambda s: self.events.put(msgpack.unpackb(s.payload.to_bytes(), raw=False)),
        )
        # The sequencer's token vanishing (a DELETE sample): it died or hangs, or our own
        # link went down; appearing again (PUT): read the task's record.
        session.liveliness().declare_subscriber(
            f"{prefix}/alive/sequencer",
            lambda s: self.events.put(GONE if s.kind == zenoh.SampleKind.DELETE else BACK),
        )

    def alive(self) -> set[str]:
        """Names of the services whose liveliness token is up."""
        alive = set()
        for reply in self.session.liveliness().get(f"{self.prefix}/alive/**", timeout=2.0):
            if reply.ok is not None:
                alive.add(str(reply.ok.key_expr).rsplit("/", 1)[-1])
        return alive

    def ask(self, key: str, request: dict[str, Any], timeout: float = 60.0) -> dict[str, Any]:
        """Query ``<prefix>/<key>`` with a MessagePack map; the decoded reply."""
        payload = msgpack.packb(request, use_bin_type=True)
        for reply in self.session.get(f"{self.prefix}/{key}", payload=payload, timeout=timeout):
            if reply.ok is None:
                err = reply.err.payload.to_bytes().decode() if reply.err is not None else "?"
                raise RuntimeError(f"{key}: {err}")
            answer: dict[str, Any] = msgpack.unpackb(reply.ok.payload.to_bytes(), raw=False)
            return answer
        raise RuntimeError(f"{key}: no reply (is the sequencer running?)")

    def control(self, action: str, task_id: str) -> dict[str, Any]:
        """``sequencer/control``: pause, resume, cancel or status of a task."""
        return self.ask("sequencer/control", {"action": action, "task_id": task_id})

    def link_cut(self) -> bool:
        """The token just vanished: did our own link go down (rather than the sequencer)?"""
        end = time.monotonic() + LINK_SETTLE_S
        while link_up(self.session):
            if time.monotonic() >= end:
                return False
            time.sleep(0.02)
        return True

    def recorded_final(self, task_id: str) -> dict[str, Any] | bool | None:
        """The task's final event from ``sequencer/history``: the event, None (it still
        runs, or no answer) or False (this sequencer does not know the task)."""
        try:
            history = self.ask("sequencer/history", {"limit": 100}, timeout=2.0)
        except RuntimeError:
            return None
        for record in history["tasks"]:
            if record["task_id"] == task_id:
                final: dict[str, Any] | None = record["final"]
                return final
        return False


def from_record(seq: Sequencer, task_id: str) -> int | None:
    """The exit status when the task's record says it ended (its final event is printed),
    or the sequencer does not know it; None: it still runs."""
    final = seq.recorded_final(task_id)
    if final is False:
        print(f"sequencer gone: the sequencer back on {seq.prefix}/alive/sequencer "
              f"does not know task {task_id}", flush=True)  # fmt: skip
        return 1
    if final is None or final is True:
        return None
    print("the final event was lost on the way: read from sequencer/history", flush=True)
    return show(final)


def show(event: dict[str, Any]) -> int | None:
    """Print one event; the exit status when it is final."""
    reason = f": {event['reason']}" if event["reason"] else ""
    print(f"event: {event['event']} step {event['step']}/{event['total']}{reason}",
          flush=True)  # fmt: skip
    if event["event"] in ("succeeded", "failed", "cancelled"):
        return 0 if event["event"] == "succeeded" else 1
    return None


def unfold_first(seq: Sequencer, task: dict[str, Any]) -> dict[str, Any] | None:
    """Submit ``task`` with the arm's own fold-out first; the reply if accepted (None: not)."""
    unfolded = dict(task, steps=[{"kind": "fold_out", "where": "--fold-out"}, *task["steps"]])
    retry = seq.ask("sequencer/submit", unfolded)
    if not retry["accepted"]:
        return None
    print("not plannable from where the arm is: unfolding it first", flush=True)
    return retry


def follow(seq: Sequencer, task_id: str, args: argparse.Namespace) -> int:
    """Print the task's events (pausing and resuming it if asked) until it ends: exit status."""
    start = time.monotonic()
    paused_at: float | None = None
    cut_at: float | None = None  # our link went down (the token with it) at
    recheck: float | None = None  # read the task's record again at
    while time.monotonic() - start < args.timeout:
        if cut_at is not None and time.monotonic() - cut_at > LINK_WAIT_S:
            print(f"no sequencer for {LINK_WAIT_S:g} s after the link went down: "
                  f"task {task_id}'s outcome is unknown", flush=True)  # fmt: skip
            return 1
        if recheck is not None and time.monotonic() >= recheck:
            status = from_record(seq, task_id)
            if status is not None:
                return status
            recheck = time.monotonic() + RECHECK_S
        now = time.monotonic() - start
        if args.pause_after is not None and paused_at is None and now >= args.pause_after:
            status = seq.control("pause", task_id)
            print(f"pause -> {status['state']} ok={status['ok']}", flush=True)
            paused_at = now
        if paused_at is not None and paused_at >= 0 and now >= paused_at + args.resume_after:
            status = seq.control("resume", task_id)
            print(f"resume -> {status['state']} ok={status['ok']}", flush=True)
            paused_at = -1.0  # done
        try:
            event = seq.events.get(timeout=0.1)
        except queue.Empty:
            continue
        if event is GONE and seq.link_cut():
            print("the link to the router went down: waiting for it and the sequencer",
                  flush=True)  # fmt: skip
            cut_at = time.monotonic()
            continue
        if event is GONE:
            print(f"sequencer gone: its liveliness token {seq.prefix}/alive/sequencer vanished "
                  f"(it died or hangs) while task {task_id} ran; its outcome is unknown",
                  flush=True)  # fmt: skip
            return 1
        if event is BACK:
            cut_at, recheck = None, time.monotonic()
            continue
        if event["task_id"] != task_id or event["event"] == "step_progress":
            continue
        status = show(event)
        if status is not None:
            return status
    print("timeout: cancelling", flush=True)
    seq.control("cancel", task_id)
    return 1


def replace_scene(seq: Sequencer, file: str) -> bool:
    """``planner/scene``: replace the scene every plan is checked against; accepted?"""
    with open(file, encoding="utf-8") as f:
        update = {"text": f.read(), "source": file, "base_version": -1}
    scene = seq.ask("planner/scene", update)
    if not scene["accepted"]:
        print(f"scene refused: {scene['error']}", flush=True)
        return False
    print(f"scene: version {scene['version']}", flush=True)
    return True


def main() -> int:
    args = parse_args()
    session = open_session(args.connect)
    try:
        seq = Sequencer(session, args.prefix)
        print(f"alive: {', '.join(sorted(seq.alive())) or 'nothing'}", flush=True)
        if args.scene and not replace_scene(seq, args.scene):
            return 2
        task = task_from_words(args.task)
        submitted = seq.ask("sequencer/submit", task)
        if not submitted["accepted"] and not args.no_fold_out:
            submitted = unfold_first(seq, task) or submitted
        if not submitted["accepted"]:
            print("refused:\n  " + "\n  ".join(submitted["errors"]), flush=True)
            return 2
        task_id = submitted["task_id"]
        print(f"accepted: task {task_id}", flush=True)
        return follow(seq, task_id, args)
    finally:
        session.close()


if __name__ == "__main__":
    sys.exit(main())
