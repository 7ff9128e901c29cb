"""A time bound on the search for a grid path on Appendix A's uniform grid.

Finding a path there (Appendix A's grid on its shifts and halvings, the traced
path) is a search whose cost a hostile contour can make
explode: a jagged polygon of a few hundred points kept the uniform grid's
router busy for minutes before it refused.  :func:`limit` sets a bound for
the search (:func:`search_bound`: it grows with the number of contour points),
and the search loops call :func:`check`, which raises :class:`TimeUp` once the
bound has passed, and the contour is refused.  Nothing after the search reads
the clock: what a found selection costs afterwards (deformation, triangulation,
recovery, quality stage, contract check, writing) is bounded by its grid, and the
same selection always gives the same mesh.  The graded grid is constructed, not
searched for: it reads no clock.

The bound lives in a context variable, so a batch's workers and the tests each
have their own; code run outside :func:`limit` is never stopped.
"""

from __future__ import annotations

import contextlib
import contextvars
import time
from collections.abc import Iterator

from .errors import TimeUp

#: Seconds every contour may search, and how many more per contour point.
SEARCH_BASE = 10.0
SEARCH_PER_POINT = 0.02

_DEADLINE: contextvars.ContextVar[tuple[float, float] | None] = contextvars.ContextVar(
    "deformesh_deadline", default=None
)


def search_bound(n_points: int) -> float:
    """Seconds the search for a grid path may take on a contour of ``n_points``."""
    return SEARCH_BASE + SEARCH_PER_POINT * n_points


@contextlib.contextmanager
def limit(seconds: float | None) -> Iterator[None]:
    """Bound the searches run inside the block to ``seconds`` from now (None: no bound;
    an enclosing bound that ends sooner stays)."""
    now = time.monotonic()
    outer = _DEADLINE.get()
    ends = now + seconds if seconds is not None else None
    if outer is not None and (ends is None or outer[0] < ends):
        ends, seconds = outer
    token = _DEADLINE.set(None if ends is None else (ends, seconds))
    try:
        yield
    finally:
        _DEADLINE.reset(token)


def check() -> None:
    """Raise :class:`TimeUp` if the bound set by :func:`limit` has passed."""
    d = _DEADLINE.get()
    if d is not None and time.monotonic() > d[0]:
        raise TimeUp(d[1])
