"""The finite-output rule at the API (deltagen.status): a row is valid only if every value
returned for it is finite, and an INVALID row's error says whether its input held NaN or
inf, or was finite but so large that the result overflows."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from deltagen import status as st
from deltagen.errors import rows_text


def finite_rows(*arrays: np.ndarray) -> np.ndarray:
    """(N,) True where every value of the row is finite in every (N, ...) array."""
    n = arrays[0].shape[0]
    ok = np.ones(n, dtype=bool)
    for a in arrays:
        ok &= np.all(np.isfinite(a.reshape(n, int(np.prod(a.shape[1:])))), axis=1)
    return ok


def mark_nonfinite(status: np.ndarray, *outs: np.ndarray) -> np.ndarray:
    """The finite-output rule for outputs transformed in Python after a kernel (a tool-frame
    Jacobian, a coupled chain's J E): OK rows whose transformed values are not all finite
    become INVALID (in place; returned). Outputs straight from a kernel need no such pass:
    its status already applies the rule."""
    status[(status == st.OK) & ~finite_rows(*outs)] = st.INVALID
    return status


def invalid_message(names: Sequence[str], inputs: Sequence[np.ndarray], rows: ArrayLike) -> str:
    """Why the ``rows`` (indices of the flattened batch) are INVALID: non-finite values in
    the inputs named ``names`` ((N, ...) arrays ``inputs``), or finite inputs whose results
    are not finite."""
    rows = np.asarray(rows, dtype=np.intp)
    listed = " or ".join(names)
    parts = []
    if inputs:
        given = finite_rows(*inputs)[rows]
        nonfinite, overflow = rows[~given], rows[given]
    else:
        nonfinite, overflow = rows, rows[:0]
    if nonfinite.size:
        verb = "contains" if len(names) == 1 else "contain"
        parts.append(f"{listed} {verb} NaN or infinite values in rows {rows_text(nonfinite)}")
    if overflow.size:
        parts.append(
            f"the result is not finite (finite {listed} too large: the arithmetic overflows) "
            f"in rows {rows_text(overflow)}"
        )
    return "; ".join(parts)
