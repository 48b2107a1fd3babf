"""``wait`` steps: time taken from the inputs."""

from __future__ import annotations

from schemas.sequencing import TaskStep
from services.sequencer.actions import Action
from services.sequencer.step import MAX_WAIT_S, NS, Phase, Step, StepContext


class WaitStep(Step):
    """``wait``: time from the inputs; a pause keeps the time left."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.end: int | None = None  # when the wait ends [ns]
        self.left = 0.0  # time left at a pause [s] (0: the whole duration)

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        if not 0.0 <= spec.duration <= MAX_WAIT_S:
            return [f"wait {spec.duration:g} s is outside 0..{MAX_WAIT_S:g} s"]
        return []

    def begin(self) -> list[Action]:
        left = self.left if self.left > 0.0 else self.spec.duration
        self.left = 0.0
        self.end = self.ctx.now + int(left * NS)
        self.phase = Phase.WAITING
        return []

    def on_tick(self) -> list[Action] | None:
        if self.phase != Phase.WAITING or self.end is None:
            return None
        left = (self.end - self.ctx.now) / NS
        if left <= 0.0:
            self.end = None
            return self.ctx.step_done()
        duration = self.spec.duration
        return self.ctx.report(1.0 - left / duration if duration > 0 else 1.0)

    def pause(self) -> list[Action] | None:
        if self.phase != Phase.WAITING or self.end is None:
            return None
        self.left = max(0.0, (self.end - self.ctx.now) / NS)
        self.end = None
        return self.ctx.paused()
