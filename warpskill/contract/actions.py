"""The nine action names of the data contract (``docs/formats.md``)."""

from __future__ import annotations

ACTIONS: tuple[str, ...] = (
    "pull_left_to_right",
    "pull_right_to_left",
    "push_left_to_right",
    "push_right_to_left",
    "pick_up",
    "put_behind",
    "put_in_front_of",
    "put_next_to",
    "put_onto",
)
"""All action names, in the order of the paper's table."""

ACTIONS_WITH_STATIC: tuple[str, ...] = tuple(a for a in ACTIONS if a.startswith("put_"))
"""Actions whose scene has a static object (the ``put_*`` actions)."""


def check_action(name: object) -> str:
    """Return ``name`` if it is one of :data:`ACTIONS`.

    Raises:
        ValueError: ``name`` is not a known action; the message lists the valid names.
    """
    if not isinstance(name, str) or name not in ACTIONS:
        raise ValueError(f"unknown action {name!r}; valid actions: {', '.join(ACTIONS)}")
    return name


def has_static_object(action: str) -> bool:
    """Whether the scene of ``action`` has a static object (raises ValueError if unknown)."""
    return check_action(action) in ACTIONS_WITH_STATIC
