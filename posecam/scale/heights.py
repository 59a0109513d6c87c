"""People's heights as the user knows them, in metres: one for everyone, a list matched to the
people tallest first, or per person id (`--height 1.72`, `--height 1.72,1.21`,
`--height 0=1.72 --height 1=1.21`). Shared by `predict` and `fuse`."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field

from posecam.errors import InputError

HEIGHT_RANGE_M = (0.5, 2.5)     # m: a --height posecam accepts (a toddler to the tallest adult; the floor's: SCALE)


def _metres(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"--height takes metres (e.g. 1.72), got {text!r}") from None
    lo, hi = HEIGHT_RANGE_M
    if not lo <= value <= hi:
        hint = " (heights are in metres, not centimetres)" if 50 <= value <= 250 else ""
        raise InputError(f"--height must lie in {lo:g}..{hi:g} m, got {text}{hint}")
    return value


@dataclass(frozen=True)
class Heights:
    """Known heights (m). `ranked` is matched to people by their estimated heights, tallest
    first; `by_id` names people by id. Empty: nothing is known."""

    ranked: tuple[float, ...] = ()
    by_id: dict[int, float] = field(default_factory=dict)

    @classmethod
    def parse(cls, values: Sequence[str]) -> Heights:
        """From the --height values: "1.72", "1.72,1.21" or "ID=1.72" (repeatable)."""
        ranked: list[float] = []
        by_id: dict[int, float] = {}
        for value in values:
            if re.fullmatch(r"\s*\d,\d\d\s*", str(value)):   # 1,72: a decimal comma, never two heights (72 m)
                raise InputError(f"--height {value.strip()} reads as two heights, the second {value.split(',')[1]} m; "
                                 f"metres take a decimal point: --height {value.strip().replace(',', '.')}")
            for part in str(value).split(","):
                part = part.strip()
                if "=" in part:
                    key, _, metres = part.partition("=")
                    if not key.strip().isdigit() or len(key.strip()) > 9:
                        raise InputError(f"--height ID=METRES needs a person id (0, 1, ...), got {part!r}")
                    by_id[int(key)] = _metres(metres)
                elif part:
                    ranked.append(_metres(part))
        if ranked and by_id:
            raise InputError("--height takes either heights by id (0=1.72) or a list (1.72,1.21), not both")
        return cls(tuple(ranked), by_id)

    def __bool__(self) -> bool:
        return bool(self.ranked or self.by_id)

    def assign(self, estimated: dict[int, float]) -> dict[int, tuple[float, str]]:
        """For each person id with an estimated height (m), the height to use and its source:
        "given" (by id, or one value for everyone) or "given, rank K" (a list matched tallest
        first, equal heights by id). People with no given height are left out."""
        if self.by_id:
            return {pid: (self.by_id[pid], "given") for pid in estimated if pid in self.by_id}
        if len(self.ranked) == 1:
            return {pid: (self.ranked[0], "given") for pid in estimated}
        order = sorted(estimated, key=lambda pid: (-estimated[pid], pid))     # equal heights: by id
        return {pid: (h, f"given, rank {k + 1}") for k, (pid, h) in enumerate(zip(order, self.ranked))}

    def doubts(self, estimated: dict[int, tuple[float, float]]) -> list[str]:
        """Where a list matched tallest first may have gone to the wrong people: each pair of
        people next in height whom the list gives different heights (or one a height, the other
        none), whose estimated heights (m, with their standard uncertainties) differ by less than
        one combined uncertainty (the order is then barely better than a coin's). Empty for
        heights by id or one height for everyone."""
        if self.by_id or len(self.ranked) < 2:
            return []
        order = sorted(estimated, key=lambda pid: (-estimated[pid][0], pid))
        given = dict(zip(order, self.ranked))
        notes = []
        for a, b in zip(order, order[1:]):
            (ha, sa), (hb, sb) = estimated[a], estimated[b]
            if given.get(a) == given.get(b) or ha - hb >= math.hypot(sa, sb):
                continue
            went = ", ".join(f"{pid} {given[pid]:.2f} m" if pid in given else f"{pid} none" for pid in (a, b))
            notes.append(f"--height {','.join(f'{h:.2f}' for h in self.ranked)} went tallest first, but persons {a} "
                         f"({ha:.2f} +- {sa:.2f} m) and {b} ({hb:.2f} +- {sb:.2f} m) are too close in height to tell "
                         f"which is taller ({went}): if that is wrong, give heights by id "
                         f"(--height {a}=M --height {b}=M)")
        return notes
