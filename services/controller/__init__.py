"""The controller: tracking loop, gripper loop and goals (docs/controller.md).

Modules: :mod:`.core` (``ControllerCore``, the deterministic core), :mod:`.tracking`
(one trajectory goal), :mod:`.laws` (default and thesis control laws),
:mod:`.estimator` (drive model and motor-angle observer), :mod:`.reference` (trajectory
plus splice blend), :mod:`.goals` (acceptance and tolerance verdicts), :mod:`.gripper`,
:mod:`.backlash` (optional belt-play compensation), :mod:`.outbox` (the messages),
:mod:`.config`, :mod:`.shell` and :mod:`.main` (``manus controller``).
"""
