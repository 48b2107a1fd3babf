"""``manus panel``: the web page for the person in the chair (docs/panel.md).

:mod:`~manus_stack.panel.tasks` (the task buttons), :mod:`~manus_stack.panel.words` (plain
language), :mod:`~manus_stack.panel.view` (what the page shows), :mod:`~manus_stack.panel.bus`
(the supervisor and jog APIs), :mod:`~manus_stack.panel.jogpad` (the pad's commands),
:mod:`~manus_stack.panel.server` (the web server); the page itself is in ``static/``.
"""
