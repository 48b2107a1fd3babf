"""The chaos soak (``manus bench chaos``): the whole stack on the simulator runs tasks
back to back while a seeded schedule injects faults, judged on the simulator's truth.

- :mod:`~manus_stack.chaos.schedule`: the faults and the tasks, as data, and the seeded
  draw of which fault hits which task when;
- :mod:`~manus_stack.chaos.watch`: the soak's own Zenoh node: every sample under the
  prefix (hashed, for the recording's completeness), the truth, task events, tokens;
- :mod:`~manus_stack.chaos.judge`: the invariants, pure functions of what was watched;
- :mod:`~manus_stack.chaos.soak`: injects each fault into the running processes and
  makes the documented recovery;
- :mod:`~manus_stack.chaos.verdict`: judges every round of a finished soak and the
  recordings' completeness (the bench's figures).
"""
