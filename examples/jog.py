"""An example jog stream: plain Zenoh + MessagePack, as a client in another language would.

It imports nothing from this project (the fields are those of ``JogCommand``, ``JogLevel``
and ``JogState`` in ``schemas/supervisor.schema.json``). It

1. sets the speed level (``<prefix>/controller/jog_level``, a Zenoh get; the reply is a
   GoalAck),
2. publishes one JogCommand on ``<prefix>/jog`` every 1 / ``--rate`` seconds for
   ``--seconds``: unitless deflections in -1..1 (scaled by the level), in the base or
   the gripper frame, or joint speeds with ``--joints``,
3. releases (a zero command) and prints the controller's ``controller/jog_state`` as it
   changes: level, whether the jog runs, why it is slowed or stopped, the gripper.

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


def main() -> int:
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
    args = parser.parse_args()
    p = args.prefix

    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([args.connect]))
    config.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(config)
    try:
        states: queue.Queue[dict[str, Any]] = queue.Queue()
        session.declare_subscriber(
            f"{p}/controller/jog_state",
            lambda s: states.put(msgpack.unpackb(s.payload.to_bytes(), raw=False)),
        )
        if args.level is not None:
            payload = msgpack.packb({"level": args.level}, use_bin_type=True)
            for reply in session.get(f"{p}/controller/jog_level", payload=payload, timeout=5.0):
                if reply.ok is None:
                    print("jog_level: error reply", flush=True)
                    return 1
                ack = msgpack.unpackb(reply.ok.payload.to_bytes(), raw=False)
                print(f"level {args.level}: {'ok' if ack['accepted'] else ack['reason']}",
                      flush=True)  # fmt: skip
                break
            else:
                print("jog_level: no reply (is the controller running?)", flush=True)
                return 1

        pub = session.declare_publisher(f"{p}/jog")
        seq = 0

        def send(**values: Any) -> None:
            nonlocal seq
            seq += 1
            cmd = {"stamp_ns": time.time_ns(), "seq": seq, "source": "examples/jog.py",
                   "units": "unitless", "frame": args.frame, **values}  # fmt: skip
            pub.put(msgpack.packb(cmd, use_bin_type=True))

        if args.joints is not None:
            push = {"kind": "joints", "joints": args.joints, "gripper": args.gripper}
        else:
            twist = {
                "linear": [args.x, args.y, args.z],
                "angular": [args.roll, args.pitch, args.yaw],
            }
            push = {"kind": "twist", "gripper": args.gripper, **twist}
        ran, refused, shown = False, "", None
        end = time.monotonic() + args.seconds
        while time.monotonic() < end:
            send(**push)
            time.sleep(1.0 / args.rate)
            while not states.empty():
                state = states.get()
                ran = ran or state["active"]
                if "refused" in state["reason"]:
                    refused = state["reason"]
                key = (state["level"], state["active"], state["reason"])
                if key != shown:  # print changes only
                    shown = key
                    xyz = [round(v * 1000.0, 1) for v in state["actual_xyz"]]
                    running = "jogging" if state["active"] else "stopped"
                    print(f"level {state['level']}/{state['levels']} {running} xyz_mm {xyz} "
                          f"{state['reason']}", flush=True)  # fmt: skip
        send(kind="stop")
        time.sleep(0.3)
        if refused:
            print(f"refused: {refused}", flush=True)
            return 1
        if not ran:
            print("the controller never reported the jog (is it running?)", flush=True)
            return 1
        print("released", flush=True)
        return 0
    finally:
        session.close()


if __name__ == "__main__":
    sys.exit(main())
