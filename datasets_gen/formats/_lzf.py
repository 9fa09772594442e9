"""LZF decompression (liblzf's format, as PCL's ``binary_compressed`` PCD files hold it).

A numba kernel, compiled and cached on first use like the methods' kernels
(:mod:`parambench.methods.numba_cache`); this module is imported only when a compressed
file is read, so other commands never load numba for it. Every read and write is bounds
checked: a damaged stream is an error code, never a read or write outside the buffers.

The stream is a sequence of chunks, each starting with a control byte ``c``: ``c < 32``
is a literal run of ``c + 1`` bytes copied from the input; otherwise ``len = c >> 5``
(7: plus the next byte) and the back-reference ``out_pos - ((c & 31) << 8) - next - 1``,
from which ``len + 2`` bytes of the output are copied one at a time (the source may
overlap the bytes being written: a run).
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np

from ...methods.numba_cache import configure_numba_cache

__all__ = ["LZFError", "lzf_decompress"]

# On-disk kernel cache where one is writable, none otherwise (see parambench.methods.numba_cache).
_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Error codes of :func:`_decode`, and what they mean.
_INPUT_OVERRUN, _BEFORE_START, _OUTPUT_OVERRUN = -1, -2, -3
_PROBLEMS = {_INPUT_OVERRUN: "the stream ends inside a chunk",
             _BEFORE_START: "a back-reference points before the start of the output",
             _OUTPUT_OVERRUN: "the stream decodes to more bytes than announced"}


class LZFError(ValueError):
    """A malformed LZF stream; ``position`` is the offset in the stream of the bad chunk."""

    def __init__(self, problem: str, position: int) -> None:
        super().__init__(problem)
        self.problem, self.position = problem, position


@numba.njit(cache=_CACHE, nogil=True)
def _decode(src, dst):
    """Decode ``src`` (uint8) into ``dst`` (uint8); (bytes written, 0) or (error code, chunk offset)."""
    n_in, n_out = src.size, dst.size
    ip, op = 0, 0
    while ip < n_in:
        start = ip
        ctrl = np.int64(src[ip])  # uint8 arithmetic would wrap in ``(ctrl & 31) << 8``
        ip += 1
        if ctrl < 32:
            run = ctrl + 1
            if ip + run > n_in:
                return _INPUT_OVERRUN, start
            if op + run > n_out:
                return _OUTPUT_OVERRUN, start
            for k in range(run):
                dst[op + k] = src[ip + k]
            ip += run
            op += run
        else:
            length = ctrl >> 5
            if length == 7:
                if ip >= n_in:
                    return _INPUT_OVERRUN, start
                length += np.int64(src[ip])
                ip += 1
            if ip >= n_in:
                return _INPUT_OVERRUN, start
            ref = op - ((ctrl & 31) << 8) - np.int64(src[ip]) - 1
            ip += 1
            length += 2
            if ref < 0:
                return _BEFORE_START, start
            if op + length > n_out:
                return _OUTPUT_OVERRUN, start
            for k in range(length):  # byte by byte: an overlapping source repeats what was just written
                dst[op + k] = dst[ref + k]
            op += length
    return op, 0


def lzf_decompress(stream, size: int) -> np.ndarray:
    """Decompress an LZF stream that must decode to exactly ``size`` bytes.

    Parameters
    ----------
    stream : bytes or (K,) numpy.ndarray of uint8
        The compressed bytes, nothing before or after them.
    size : int
        The announced decompressed size (the caller bounds it before this allocates it).

    Returns
    -------
    (size,) numpy.ndarray of uint8

    Raises
    ------
    LZFError
        A chunk cut short by the end of the stream, a back-reference before the start of
        the output, more output than ``size``, or less.
    """
    src = np.frombuffer(stream, dtype=np.uint8) if not isinstance(stream, np.ndarray) else stream
    dst = np.empty(int(size), dtype=np.uint8)
    written, position = _decode(src, dst)
    if written < 0:
        raise LZFError(_PROBLEMS[int(written)], int(position))
    if written != size:
        raise LZFError(f"the stream decodes to {int(written)} bytes, not the {int(size)} announced", len(src))
    return dst
