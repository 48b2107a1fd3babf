"""An example jog stream: plain Zenoh + MessagePack, as a client in another language would.

It imports nothing from this project (the fields are those of ``JogCommand``, ``JogLevel``
and ``JogState`` in ``schemas/supervisor.schema.json``). It

1. sets the speed level (``<prefix>/controller/jog_level``, a Zenoh get; the reply is a
   GoalAck),
2. publishes one JogCommand on ``<prefix>/jog`` every 1 / ``--rate`` seconds for
   ``--seconds``: unitless deflections in -1..1 (scaled by the level), in the base or
   the gripper frame, or joint speeds with ``--joints``,
3. releases (a zero command) and prints the controller's ``controller/jog_state`` as it
   changes: level, whether the jog runs (``state``), what holds it back (``limits``: the
   level's speed cap, a joint limit, a singularity, the collision guard) or why it
   stopped (``cause``), the gripper.

    python examples/jog.py --connect tcp/127.0.0.1:7447 --level 2 --x 0.5 --seconds 2
    python examples/jog.py --frame gripper --z -0.3 --gripper 0.5
    python examples/jog.py --joints 0 0 0 0 0 0.5 --seconds 1

Stop publishing and the controller's deadman (150 ms) stops the arm by itself. Exit
status: 0 when the jog ran and was released, 1 when the controller refused it or never
reported it (the reason is printed).
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
import time
from typing import Any

import msgpack
import zenoh


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--connect", default="tcp/127.0.0.1:7447", help="router endpoint")
    parser.add_argument("--prefix", default="manus", help="key prefix of the arm")
    parser.add_argument("--level", type=int, default=None, help="speed level (1..5)")
    parser.add_argument("--frame", choices=("base", "gripper"), default="base")
    for axis in ("x", "y", "z", "roll", "pitch", "yaw"):
        parser.add_argument(f"--{axis}", type=float, default=0.0, help=f"{axis} deflection -1..1")
    parser.add_argument("--joints", type=float, nargs=6, default=None, metavar="D",
                        help="joint deflections q1..q6 instead of a twist")  # fmt: skip
    parser.add_argument("--gripper", type=float, default=0.0, help="open (+) / close (-)")
    parser.add_argument("--rate", type=float, default=20.0, help="commands per second")
    parser.add_argument("--seconds", type=float, default=2.0, help="how long to push")
    return parser.parse_args()


def open_session(endpoint: str) -> zenoh.Session:
    """A client of the router at ``endpoint``, loopback only: no scouting."""
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


def set_level(session: zenoh.Session, prefix: str, level: int) -> bool:
    """``controller/jog_level``: True when the controller accepted the level."""
    payload = msgpack.packb({"level": level}, use_bin_type=True)
    for reply in session.get(f"{prefix}/controller/jog_level", payload=payload, timeout=5.0):
        if reply.ok is None:
            print("jog_level: error reply", flush=True)
            return False
        ack = msgpack.unpackb(reply.ok.payload.to_bytes(), raw=False)
        print(f"level {level}: {'ok' if ack['accepted'] else ack['reason']}", flush=True)
        return bool(ack["accepted"])
    print("jog_level: no reply (is the controller running?)", flush=True)
    return False


def the_push(args: argparse.Namespace) -> dict[str, Any]:
    """The JogCommand fields the stream repeats (deflections, unitless)."""
    if args.joints is not None:
        return {"kind": "joints", "joints": args.joints, "gripper": args.gripper}
    twist = {"linear": [args.x, args.y, args.z], "angular": [args.roll, args.pitch, args.yaw]}
    return {"kind": "twist", "gripper": args.gripper, **twist}


class Watch:
    """The controller's JogState as it changes: printed, and what the exit status needs."""

    def __init__(self) -> None:
        self.states: queue.Queue[dict[str, Any]] = queue.Queue()
        self.ran, self.refused = False, ""
        self._shown: tuple[Any, ...] | None = None

    def on_sample(self, sample: zenoh.Sample) -> None:
        self.states.put(msgpack.unpackb(sample.payload.to_bytes(), raw=False))

    def drain(self) -> None:
        """Decide on the typed fields (state, cause, limits); print the words with them."""
        while not self.states.empty():
            state = self.states.get()
            self.ran = self.ran or state["state"] == "running"
            if state["state"] == "stopped" and state["cause"] in ("bad_command", "not_ready"):
                self.refused = state["reason"]
            limits = tuple((lim["kind"], lim["object"]) for lim in state["limits"])
            key = (state["level"], state["state"], state["cause"], limits)
            if key != self._shown:  # print changes only
                self._shown = key
                xyz = [round(v * 1000.0, 1) for v in state["actual_xyz"]]
                doing = "jogging" if state["state"] == "running" else state["state"]
                print(f"level {state['level']}/{state['levels']} {doing} xyz_mm {xyz} "
                      f"{state['reason']}", flush=True)  # fmt: skip


def main() -> int:
    args = parse_args()
    session = open_session(args.connect)
    try:
        watch = Watch()
        session.declare_subscriber(f"{args.prefix}/controller/jog_state", watch.on_sample)
        if args.level is not None and not set_level(session, args.prefix, args.level):
            return 1
        pub = session.declare_publisher(f"{args.prefix}/jog")
        seq = 0

        def send(**values: Any) -> None:
            nonlocal seq
            seq += 1
            cmd = {"stamp_ns": time.time_ns(), "seq": seq, "source": "examples/jog.py",
                   "units": "unitless", "frame": args.frame, **values}  # fmt: skip
            pub.put(msgpack.packb(cmd, use_bin_type=True))

        push = the_push(args)
        end = time.monotonic() + args.seconds
        while time.monotonic() < end:
            send(**push)
            time.sleep(1.0 / args.rate)
            watch.drain()
        send(kind="stop")
        time.sleep(0.3)
        watch.drain()
        if watch.refused:
            print(f"refused: {watch.refused}", flush=True)
            return 1
        if not watch.ran:
            print("the controller never reported the jog (is it running?)", flush=True)
            return 1
        print("released", flush=True)
        return 0
    finally:
        session.close()


if __name__ == "__main__":
    sys.exit(main())
