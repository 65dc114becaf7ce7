"""The configurable window of plausible input dates, checked without heavy imports.

``[instrument] earliest_date`` and ``latest_date`` (see :mod:`cwproc.io.timecheck`,
which applies them) are ISO dates within the span of the products' nanosecond times.
"""

from __future__ import annotations

import datetime
from typing import Any

#: first and last date a configured window may name: datetime64[ns] holds 1677-2262
DATE_MIN = "1678-01-01"
DATE_MAX = "2261-12-31"


def check_iso_dates(obj: Any, *names: str) -> None:
    """Each named attribute of ``obj`` empty or an ISO date within DATE_MIN..DATE_MAX.

    Raises
    ------
    ValueError
        Naming the key and the value (the configuration loader adds the file).
    """
    for name in names:
        value = getattr(obj, name)
        if value == "":
            continue
        try:
            ok = len(value) == 10 and DATE_MIN <= datetime.date.fromisoformat(value).isoformat()
            ok = ok and value <= DATE_MAX
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(
                f"{name}: must be an ISO date yyyy-mm-dd within {DATE_MIN}..{DATE_MAX}, "
                f"got {value!r}"
            )
