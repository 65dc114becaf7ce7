"""The dissipation rate of a streamed day, group by group as the chunks complete blocks.

:func:`cwproc.stages.epsilon.estimate_epsilon` fits a day's blocks in groups of
:data:`~cwproc.stages.epsilon.EPSILON_CELLS` cells (:func:`~cwproc.stages.epsilon.block_groups`);
each group's estimates depend on its own blocks, the settings and the day's heights only.
While a day is streamed (:mod:`cwproc.pipeline.stream`), each group is estimated in the
caller's thread as soon as the chunks have made its blocks (:class:`EpsilonAhead`), beside
the reading and screening of the next chunks in their threads, instead of after the last
chunk with the other core idle. The day's :func:`~cwproc.stages.epsilon.estimate_epsilon`
takes a group estimated ahead only where the day's own group has the same rows, the same
data and attributes and the same settings (:func:`~cwproc.stages.epsilon.group_key`), and
estimates the others itself: the product is that of the day estimated at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import xarray as xr

from cwproc.physics.exact_lag import is_cw_probe
from cwproc.physics.transfer import Probe
from cwproc.stages.epsilon import EPSILON_CELLS, GroupEstimate, estimate_group
from cwproc.stages.structure import INSTRUMENT_SETTINGS


def with_day_attrs(sf: xr.Dataset, attrs: dict) -> xr.Dataset:
    """``sf`` with the instrument settings of the day's attributes ``attrs`` (those the
    whole-day run's structure function carries: the instrument and
    :data:`~cwproc.stages.structure.INSTRUMENT_SETTINGS`; a setting the day lacks is
    dropped). A shallow copy: the variables are shared."""
    out = sf.copy(deep=False)
    out.attrs = dict(sf.attrs)
    out.attrs["instrument"] = str(attrs.get("instrument", ""))
    for key in INSTRUMENT_SETTINGS:
        out.attrs.pop(key, None)
        if key in attrs:
            out.attrs[key] = attrs[key]
    return out


@dataclass
class EpsilonAhead:
    """Groups of blocks of a streamed day estimated as soon as their blocks are made.

    ``options`` are the keyword arguments of the day's
    :func:`~cwproc.stages.epsilon.estimate_epsilon` (probe, lag number, model); ``join``
    joins structure-function pieces along ``time`` as the day's are joined. A cw probe
    (whose noise is pooled over neighbouring blocks) is estimated whole, so nothing is
    done ahead for it; an error while estimating ahead stops it (the day's estimate
    meets it again and words it).
    """

    probe: Probe
    options: dict
    join: Callable[[list[xr.Dataset]], xr.Dataset]
    done: list[GroupEstimate] = field(default_factory=list)
    #: what the groups share (``fit_setup``), handed to the day's estimate
    memo: dict = field(default_factory=dict)
    #: blocks of the day estimated so far
    blocks: int = 0
    enabled: bool = True

    def __post_init__(self) -> None:
        self.enabled = self.enabled and not is_cw_probe(self.probe)

    def advance(self, pieces: list[xr.Dataset], attrs: Callable[[], dict]) -> None:
        """Estimate every complete group of the day's blocks in ``pieces`` (the chunks'
        structure functions so far) not estimated yet; ``attrs()`` gives the day's
        attributes as far as known."""
        if not self.enabled or not pieces:
            return
        step = max(1, EPSILON_CELLS // max(int(pieces[0].sizes["height"]), 1))
        sizes = [int(piece.sizes["time"]) for piece in pieces]
        if sum(sizes) - self.blocks < step:
            return
        day = attrs()
        try:
            while sum(sizes) - self.blocks >= step:
                rows = slice(self.blocks, self.blocks + step)
                group = with_day_attrs(_rows_of(pieces, sizes, rows, self.join), day)
                self.done.append(
                    estimate_group(group, rows, probe=self.probe, memo=self.memo, **self.options)
                )
                self.blocks = rows.stop
        except Exception:  # the day's estimate_epsilon estimates this group and words it
            self.enabled = False


def _rows_of(
    pieces: list[xr.Dataset],
    sizes: list[int],
    rows: slice,
    join: Callable[[list[xr.Dataset]], xr.Dataset],
) -> xr.Dataset:
    """Blocks ``rows`` of the day whose blocks are ``pieces`` (of ``sizes`` blocks) in
    order, joined from the pieces that hold them."""
    start = 0
    held: list[xr.Dataset] = []
    first = None
    for piece, size in zip(pieces, sizes, strict=True):
        if start + size > rows.start and start < rows.stop:
            if first is None:
                first = start
            held.append(piece)
        start += size
    joined = join(held)
    return joined.isel(time=slice(rows.start - first, rows.stop - first))
