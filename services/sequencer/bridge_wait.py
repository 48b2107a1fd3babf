"""A task submitted while the bridge is still starting waits for it, a bounded time.

A task starts only when the bridge is in phase ``running`` and a valid joint state has
come (the arm's configuration is where its first move is planned from). Right after
``manus up`` or a restart of the bridge, the bridge is on its way there by itself:
waiting for the arm's power-up, entering joint mode, making its start-up moves (or a
resync, or a fold in progress: ``schemas.state.ON_ITS_WAY_PHASES``). A submission that
only this keeps from starting is **held** (:class:`BridgeWait`), at most
``SequencerConfig.bridge_wait_s`` (default 30 s) from its arrival: once the bridge runs
and a valid joint state is in, it is validated and started as if it had just arrived;
if the bridge enters a phase it does not leave by itself (stopped, estopped, arm_error,
shutdown) it is refused at once with that phase and its detail, and so it is at the end
of the wait, with the phase reached. With the bridge running, required services this
sequencer has not seen up yet since it started are waited for the same way (``manus up``
starts them together, and under load the sequencer may hear their tokens after it heard
the bridge run); one seen up and then gone, or one missing while the bridge is not running,
refuses it at once. Any other reason (a task running) still refuses a submission at once,
and so does a bridge already in one of those phases. One submission is held at a time;
another one meanwhile is refused as busy. Time is the core's (``now_ns`` of its inputs),
so this is deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.sequencing import SubmitReply, Task, TaskState, TaskStatus
from schemas.state import ON_ITS_WAY_PHASES, BridgePhase

NS = 1_000_000_000


def bridge_on_its_way(phase: str, valid_joint_state: bool) -> bool:
    """Whether the bridge will be ready for a task by itself: on its way to ``running``
    (no state yet included), or running without a valid joint state yet."""
    if phase == BridgePhase.RUNNING:
        return not valid_joint_state
    return phase == "" or phase in ON_ITS_WAY_PHASES


@dataclass(frozen=True)
class Held:
    """A submission waiting for the bridge.

    Attributes:
        task_id: the id it gets if accepted.
        task: the task.
        since_ns: when it arrived [ns].
        until_ns: when the wait ends [ns].
    """

    task_id: str
    task: Task
    since_ns: int
    until_ns: int


class BridgeWait:
    """The submission held while the bridge starts (see the module docstring).

    Args:
        wait_s: the longest wait [s] (0: none, refuse at once as before).
    """

    def __init__(self, wait_s: float) -> None:
        self.wait_s = wait_s
        self.held: Held | None = None

    def hold(self, task_id: str, task: Task, now_ns: int) -> bool:
        """Hold ``task`` (True), unless waiting is off or a submission is held already."""
        if self.wait_s <= 0.0 or self.held is not None:
            return False
        self.held = Held(task_id, task, now_ns, now_ns + round(self.wait_s * NS))
        return True

    def busy(self) -> str:
        """Why another submission is refused meanwhile ('' when none is held)."""
        held = self.held
        if held is None:
            return ""
        return (
            f"busy: task {held.task_id} waits for the bridge to run; submit again once it "
            "is accepted or refused"
        )

    def late(
        self, held: Held, phase: str, detail: str, now_ns: int, missing: list[str]
    ) -> SubmitReply:
        """The refusal of ``held`` at the end of its wait (the bridge in ``phase``, the
        required services ``missing`` never seen up)."""
        waited = f"waited {(now_ns - held.since_ns) / NS:.1f} s"
        if missing:
            error = (
                f"required service(s) not running: {', '.join(missing)} (not up within "
                f"{self.wait_s:g} s of the submission, bridge_wait_s; {waited})"
            )
        else:
            seen = f"{phase}: {detail}" if detail else phase or "no state/bridge received"
            error = (
                f"the bridge did not get ready within {self.wait_s:g} s (bridge_wait_s; "
                f"{waited}, phase {seen}); a task starts only in phase running, with a "
                "valid joint state"
            )
        return SubmitReply(accepted=False, task_id="", errors=[error])

    def status(self, phase: str, missing: list[str]) -> TaskStatus:
        """What ``sequencer/status`` says of the held submission (the bridge in ``phase``,
        the required services ``missing``)."""
        held = self.held
        assert held is not None
        return TaskStatus(
            ok=True,
            task_id=held.task_id,
            state=TaskState.VALIDATING,
            step=-1,
            total=len(held.task.steps),
            progress=0.0,
            message=(
                f"waiting for {', '.join(missing)} to start, at most {self.wait_s:g} s"
                if missing
                else f"waiting for the bridge to run (phase {phase or 'unknown'}), "
                f"at most {self.wait_s:g} s"
            ),
        )
