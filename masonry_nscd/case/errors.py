"""The error of an invalid case: one readable line per problem, each naming its field."""

from __future__ import annotations

from collections.abc import Sequence

from pydantic_core import PydanticCustomError


class CaseError(Exception):
    """An invalid case file or override.

    ``messages`` holds one readable line per problem, each starting with the field path
    (``joint.d_spring: got 1.2; ...``) or with the file when the problem is the file itself.
    ``str(error)`` is the messages joined by newlines.
    """

    def __init__(self, messages: str | Sequence[str]):
        if isinstance(messages, str):
            messages = [messages]
        self.messages: list[str] = [str(m) for m in messages] or ["invalid case"]
        super().__init__("\n".join(self.messages))


def raise_problems(problems: list[tuple[str, str]]) -> None:
    """Raise the consistency problems of one section as one pydantic error.

    Each problem is ``(field, text)``, the field relative to the section; the formatter of
    :class:`CaseError` turns each into a message with the full path.
    """
    if problems:
        summary = "; ".join(f"{field}: {text}" for field, text in problems)
        raise PydanticCustomError(
            "case_consistency", "{summary}", {"summary": summary, "problems": problems}
        )
