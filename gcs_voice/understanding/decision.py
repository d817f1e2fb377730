"""The matcher's verdict on one utterance: an action class, or *no action* with the reason why."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from gcs_voice.domain.amounts import Amount

__all__ = ["Decision"]


@dataclass(frozen=True)
class Decision:
    """Action or no action, with its evidence.

    ``action`` is a class id from ``gcs_voice.domain.dictionary.ACTIONS`` or None (do nothing);
    ``phrase`` the dictionary phrase that won (also kept when rejected, to show what was near);
    ``score`` the matcher's confidence in [0, 1] (1 = certain); ``reason`` a short human sentence,
    always set when ``action`` is None.
    """

    action: str | None
    text: str
    phrase: str | None = None
    lang: str | None = None
    score: float = 0.0
    reason: str = ""
    matcher: str = ""
    #: how far, when an amount was said with the command ("go forward three metres"): the motion is bounded
    amount: Amount | None = None
    #: no action because the speech went on past a command's words (the engine said so): talk, not a command
    #: misheard; a pilot is not asked to speak up over the room for it
    went_on: bool = False

    @property
    def label(self) -> str:
        """The action as a pilot would say it back: "go_forward 3 m", "turn_left 45°", "stop"."""
        return f"{self.action} {self.amount.label}" if self.action and self.amount else (self.action or "")

    @property
    def accepted(self) -> bool:
        return self.action is not None

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["amount"] = self.amount.to_dict() if self.amount else None
        return out
