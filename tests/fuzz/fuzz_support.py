"""Shared pieces of the fuzz tests: the case counter, the example counts of the profiles, the
strategies of awkward numbers and the check that a refusal names its object and its problem."""
from __future__ import annotations

import os

import numpy as np
from hypothesis import strategies as st

PROFILE = "ci"
CASES = 0
# One test (all its examples): the ci profile's slowest takes about a minute, five times that
# under the sanitizers (tools/test_sanitize.py sets BSGI_SANITIZED).
HANG_SECONDS = 1500 if os.environ.get("BSGI_SANITIZED") else 300
SCALE = {"ci": 1, "long": 20}

# Debugging a crash: BSGI_FUZZ_TRACE=path writes each case's input there before it runs, so the
# input that took the process down is in the file afterwards (it then becomes a regular test).
TRACE = os.environ.get("BSGI_FUZZ_TRACE")


def examples(n: int) -> int:
    """The profile's number of examples for a test whose ci share is n."""
    return n * SCALE.get(PROFILE, 1)


def case(**inputs) -> None:
    global CASES
    CASES += 1
    if TRACE:
        with open(TRACE, "w") as f:
            f.write(repr(inputs) + "\n")


# Numbers: ordinary ones, and the edges (0, tiny, huge, negative, NaN, inf).
EDGE = [0.0, -0.0, 1.0, -1.0, 1e-300, 1e-12, 1e12, 1e300, -1e300, float("nan"), float("inf"), float("-inf")]
any_float = st.one_of(st.floats(-10, 10), st.sampled_from(EDGE), st.floats(allow_nan=True, allow_infinity=True))
finite_float = st.one_of(st.floats(-10, 10), st.floats(-1e6, 1e6), st.sampled_from([0.0, 1e-300, 1e-12, 1e12, -1e12]))
unit_float = st.one_of(st.floats(0, 1), st.sampled_from([0.0, 1.0, 1e-12, 1 - 1e-12]))
small_int = st.integers(-3, 12)


def arrays(shape, elements=any_float):
    """A float64 array of the given shape (a tuple or a strategy of tuples)."""
    shape_st = shape if isinstance(shape, st.SearchStrategy) else st.just(shape)
    return shape_st.flatmap(lambda s: st.lists(elements, min_size=int(np.prod(s)), max_size=int(np.prod(s)))
                            .map(lambda v, s=s: np.array(v, np.float64).reshape(s)))


def points(width: int, max_rows: int = 8, elements=any_float):
    """(N, width) arrays, and now and then a wrong shape."""
    good = st.integers(0, max_rows).map(lambda n: (n, width))
    bad = st.sampled_from([(width,), (2, width + 1), (1, 1, width), (0,)])
    return arrays(st.one_of(good, good, good, bad), elements)


def rgb(elements=unit_float):
    return st.one_of(st.lists(elements, min_size=3, max_size=3),
                     st.lists(any_float, min_size=0, max_size=4))


def refused(error: BaseException, *names: str) -> None:
    """A refusal is a ValueError (or a MemoryError for sizes, an IndexError for indices) whose
    message names one of the objects given and says something beyond the name."""
    assert isinstance(error, (ValueError, MemoryError, IndexError, TypeError)), repr(error)
    message = str(error)
    assert any(n.lower() in message.lower() for n in names), f"message {message!r} names none of {names}"
    assert len(message) > max(len(n) for n in names) + 8, f"message {message!r} does not say the problem"


def finite(a, what="result") -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    assert np.isfinite(a).all(), f"{what} is not finite: {a}"
    return a


def usable(directions) -> np.ndarray:
    """Rows that are directions the core maps: finite, of length 1e-150 to 1e150 (squares that
    neither underflow nor overflow); others give NaN by design (hemisphere_map.h)."""
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    with np.errstate(all="ignore"):
        n = np.sqrt((np.abs(d) ** 2).sum(axis=1))
        return np.isfinite(d).all(axis=1) & (n > 1e-150) & (n < 1e150)
