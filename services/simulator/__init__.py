"""The Manus simulator (``manus sim``): the arm's electronics as a python-can peer.

``core`` (:class:`SimCore`, the deterministic timeline) drives ``controller`` (command
execution), ``arm`` (mechanics: ``drives``, ``workspace``, ``cartesian``), ``report``
(the frames), ``messages`` (status messages), ``replies`` (frames from the PC), ``faults``
and ``arm_faults``; ``config`` holds every parameter. Shells: ``live`` (real time on any
python-can bus), ``slcan`` and ``slcan_socket`` (an slcan adapter on a pty, on 127.0.0.1),
``nodes`` (one adapter per PC-side node), ``shell`` (Zenoh truth),
``main`` (the command); ``scripted`` and ``stepresponse`` drive the core in lock-step.
"""
