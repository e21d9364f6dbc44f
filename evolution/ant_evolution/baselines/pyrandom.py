"""Python's ``random`` module, compiled: the same draws from the same state, in numba.

neat-python draws every random number from the standard library's ``random`` module (one
Mersenne Twister, MT19937, shared by the process). Its connection-gene mutation makes
about five draws for each of some 150,000 genes a generation, in Python. The functions
here run the same generator on a copy of that state inside compiled loops:

* :func:`take_state` / :func:`put_state` move the module's state (``random.getstate()``:
  624 words, the position, and ``gauss``'s cached second value) into arrays and back;
* :func:`uniform01` is ``random.random()`` (CPython's ``random_random``: two 32-bit
  words, 53 bits) and :func:`gauss` is ``random.gauss`` (Box-Muller with the cached
  second value, ``math`` functions as in ``random.py``).

Every value and the state left behind are the module's own, bit for bit
(``tests/test_baselines.py`` holds them to the module on long runs of draws), so code that
uses them draws exactly what the library would have drawn.
"""

from __future__ import annotations

import math
import random

import numba as nb
import numpy as np

N = 624
"""Words of the Mersenne Twister's state."""
_M = 397
# unsigned constants: numba keeps every word's arithmetic in uint64
_MATRIX_A = np.uint64(0x9908B0DF)
_UPPER = np.uint64(0x80000000)
_LOWER = np.uint64(0x7FFFFFFF)
_ZERO = np.uint64(0)
_ONE = np.uint64(1)
_TEMPER_B = np.uint64(0x9D2C5680)
_TEMPER_C = np.uint64(0xEFC60000)
_S1, _S5, _S6, _S7 = np.uint64(1), np.uint64(5), np.uint64(6), np.uint64(7)
_S11, _S15, _S18 = np.uint64(11), np.uint64(15), np.uint64(18)
TWOPI = 2.0 * math.pi


def take_state() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``random`` module's state as ``(words uint64[624], position int64[1], gauss)``.

    ``gauss`` is ``float64[2]``: ``[1, value]`` when ``random.gauss`` holds a cached
    second value, ``[0, 0]`` otherwise.
    """
    version, internal, gauss_next = random.getstate()
    if version != 3 or len(internal) != N + 1:
        raise RuntimeError(f"random module state version {version}: expected 3 (MT19937)")
    words = np.array(internal[:N], dtype=np.uint64)
    position = np.array([internal[N]], dtype=np.int64)
    cached = np.array([0.0, 0.0] if gauss_next is None else [1.0, gauss_next])
    return words, position, cached


def put_state(words: np.ndarray, position: np.ndarray, cached: np.ndarray) -> None:
    """Set the ``random`` module's state from :func:`take_state`'s arrays."""
    gauss_next = float(cached[1]) if cached[0] else None
    random.setstate((3, (*words.tolist(), int(position[0])), gauss_next))


@nb.njit(cache=True, inline="always")
def _word(words, position):
    """The generator's next 32-bit output (``genrand_uint32`` of CPython's ``_random``)."""
    if position[0] >= N:
        for k in range(N - _M):
            y = (words[k] & _UPPER) | (words[k + 1] & _LOWER)
            words[k] = words[k + _M] ^ (y >> _S1) ^ (_MATRIX_A if y & _ONE else _ZERO)
        for k in range(N - _M, N - 1):
            y = (words[k] & _UPPER) | (words[k + 1] & _LOWER)
            words[k] = words[k + _M - N] ^ (y >> _S1) ^ (_MATRIX_A if y & _ONE else _ZERO)
        y = (words[N - 1] & _UPPER) | (words[0] & _LOWER)
        words[N - 1] = words[_M - 1] ^ (y >> _S1) ^ (_MATRIX_A if y & _ONE else _ZERO)
        position[0] = 0
    y = words[position[0]]
    position[0] += 1
    y ^= y >> _S11
    y ^= (y << _S7) & _TEMPER_B
    y ^= (y << _S15) & _TEMPER_C
    y ^= y >> _S18
    return y


@nb.njit(cache=True, inline="always")
def uniform01(words, position):
    """``random.random()``: a 53-bit float in [0, 1) from two words."""
    a = _word(words, position) >> _S5
    b = _word(words, position) >> _S6
    return (a * 67108864.0 + b) * (1.0 / 9007199254740992.0)


@nb.njit(cache=True, inline="always")
def gauss(words, position, cached, mu, sigma):
    """``random.gauss(mu, sigma)``, with its cached second value in ``cached``."""
    if cached[0] != 0.0:
        z = cached[1]
        cached[0] = 0.0
        cached[1] = 0.0
    else:
        x2pi = uniform01(words, position) * TWOPI
        g2rad = math.sqrt(-2.0 * math.log(1.0 - uniform01(words, position)))
        z = math.cos(x2pi) * g2rad
        cached[0] = 1.0
        cached[1] = math.sin(x2pi) * g2rad
    return mu + z * sigma


@nb.njit(cache=True)
def draws(words, position, cached, kinds):
    """A run of draws, for tests: ``kinds[i]`` 0 is ``random()``, 1 ``gauss(0.5, 2.0)``."""
    out = np.empty(kinds.shape[0])
    for i in range(kinds.shape[0]):
        if kinds[i] == 0:
            out[i] = uniform01(words, position)
        else:
            out[i] = gauss(words, position, cached, 0.5, 2.0)
    return out
