"""What the sequencer's core asks of its shell: queries to send, messages to publish, and
the answers to submitted tasks (:class:`Reply`).

The core returns a list of these from every input; the live shell
(:mod:`services.sequencer.shell`) and the lock-step harness
(:mod:`manus_stack.task_lockstep`) carry them out, each in its way.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas import endpoints as ep
from schemas.base import Message
from schemas.sequencing import SubmitReply

EVENTS_SUFFIX = ep.EVENTS
HEARTBEAT_SUFFIX = ep.HEARTBEAT
"""Key suffix of the deadman heartbeat (``schemas.control.Heartbeat``)."""


@dataclass(frozen=True)
class Query:
    """Send ``request`` to the queryable ``<prefix>/<suffix>``; answer with ``token``
    (:meth:`SequencerCore.on_reply <services.sequencer.core.SequencerCore.on_reply>`)."""

    token: int
    suffix: str
    request: Message
    reply_type: type[Message]


@dataclass(frozen=True)
class Publish:
    """Publish ``message`` on ``<prefix>/<suffix>``."""

    suffix: str
    message: Message


@dataclass(frozen=True)
class Reply(Publish):
    """The answer to a submitted task: ``message`` (a
    :class:`~schemas.sequencing.SubmitReply`) goes back on the queryable ``suffix``
    (:data:`schemas.endpoints.SUBMIT`), to the submitter of ``submission`` (the task id given to
    :meth:`SequencerCore.submit <services.sequencer.core.SequencerCore.submit>`) only.

    A :class:`Publish` in that it goes out on a key (Zenoh sends a query's reply on the
    queryable's key), but to one peer: check for it before :class:`Publish`.
    """

    submission: str = ""

    @property
    def reply(self) -> SubmitReply:
        """The answer."""
        assert isinstance(self.message, SubmitReply)
        return self.message


Action = Query | Publish
"""Every output of the core (a :class:`Reply` is a :class:`Publish`)."""
