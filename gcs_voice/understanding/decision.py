"""The matcher's verdict on one utterance: an action class, or *no action* with the reason why."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

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

    @property
    def accepted(self) -> bool:
        return self.action is not None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)
