"""Results of high-level operations, and the collector that gathers COMMAND_ACKs and STATUSTEXTs for one.

A refusal's reason is what the vehicle said: ArduCopter answers ARM with FAILED plus one CRITICAL
"Arm: ..." text per failing check; PX4 with TEMPORARILY_REJECTED plus "Arming denied: ...". Texts of
severity WARNING or worse that arrive while an operation waits are its reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink

from gcs_voice.link.state import CommandAck, StatusText, enum_name, result_name

__all__ = ["OperationResult", "AckCollector", "ACCEPTED", "REFUSED", "TIMED_OUT", "command_name"]

ACCEPTED, REFUSED, TIMED_OUT = "accepted", "refused", "timed out"


def command_name(command: int) -> str:
    return enum_name("MAV_CMD", command, unknown="COMMAND")


@dataclass(frozen=True)
class OperationResult:
    """``status`` is accepted / refused / timed out; ``reason`` one human line; ``texts`` what the vehicle said."""

    operation: str
    status: str
    reason: str = ""
    texts: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.status == ACCEPTED

    def __str__(self) -> str:
        return f"{self.operation}: {self.status}" + (f" ({self.reason})" if self.reason else "")


@dataclass(eq=False)
class AckCollector:
    """Everything acknowledged or said since the operation started (filled by the link's reader thread).

    Compared by identity: with value equality, ``list.remove`` of one operation's collector could take
    out another's with equal contents (two operations at once, e.g. take-off and a telemetry request),
    and the second removal then failed ("take_off failed: list.remove(x): x not in list", seen under load).
    """

    acks: list[CommandAck] = field(default_factory=list)
    texts: list[StatusText] = field(default_factory=list)

    def take(self, event: CommandAck | StatusText) -> None:
        (self.acks if isinstance(event, CommandAck) else self.texts).append(event)

    def acks_for(self, command: int) -> list[CommandAck]:
        return [a for a in self.acks if a.command == command]

    def warnings(self) -> list[str]:
        """Texts of severity WARNING (4) or worse, in order, without repeats."""
        seen: list[str] = []
        for text in self.texts:
            if text.severity <= mavlink.MAV_SEVERITY_WARNING and text.text not in seen:
                seen.append(text.text)
        return seen

    def reason(self, ack: CommandAck | None) -> str:
        """"FAILED: Arm: Need Position Estimate; Arm: ..." or the ACK result alone."""
        said = "; ".join(self.warnings())
        head = f"{command_name(ack.command)} {result_name(ack.result)}" if ack else ""
        return ": ".join(p for p in (head, said) if p)
