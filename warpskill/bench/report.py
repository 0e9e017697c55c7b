"""What the benchmarks show and keep: their tables on the standard output, their outcome tables on disk.

The tables a benchmark prints are the output the user asked for, so :func:`show` prints them (the
one place in the benchmarks that does); per-case progress goes through :mod:`logging`
(``warpskill.bench.*`` loggers), which the command line shows as lines of its own.
"""

from __future__ import annotations

import os
from pathlib import Path

from warpskill.bench.outcomes import (
    CaseOutcome,
    close_calls,
    close_choices,
    flip_report,
    load_outcomes,
    save_outcomes,
    write_outcomes,
)


def show(*blocks: str) -> None:
    """Print each block of a benchmark's report (a table, a summary line; empty: a blank line)."""
    for block in blocks:
        print(block, flush=True)


def record_outcomes(out: str | os.PathLike | None, outcomes: list[CaseOutcome], *,
                    baseline: str | os.PathLike | None = None,
                    save_baseline: str | os.PathLike | None = None) -> None:
    """What every success benchmark does with its outcomes at the end: write the table into
    ``out`` (if any), show the closest calls (where the outcomes have margins) and choices (where
    they have hypotheses on both sides of the static), the flips since
    ``baseline`` (if any), save a copy as ``save_baseline`` (if any)."""
    if out is not None:
        show(f"\noutcome table: {write_outcomes(out, outcomes)}")
    for line in (close_calls(outcomes), close_choices(outcomes)):
        if line:
            show(line)
    if baseline is not None:
        show("", flip_report(load_outcomes(baseline), {o.case: o for o in outcomes}, name=str(baseline)))
    if save_baseline is not None:
        Path(save_baseline).parent.mkdir(parents=True, exist_ok=True)
        save_outcomes(save_baseline, outcomes)
        show(f"baseline saved: {save_baseline}")
