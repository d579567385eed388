"""Checks a reader makes on what it takes from a file: links that resolve inside the file,
arrays of finite real numbers of the expected shape, attributes of the expected type and range.

Each check raises :class:`SchemaError` with one line naming the file, the HDF5 object and what
is wrong; the readers (:func:`slippulse.core.h5io.read_pulse`, the run and seed readers) compose
them, so that no command computes with a NaN, a complex number, a string where a boolean belongs
or a link to another file.
"""
from __future__ import annotations

import math

import h5py
import numpy as np

from .errors import SchemaError


def where(h5obj, path: str | None = None) -> str:
    """'FILE: /group' for messages."""
    return f"{path or h5obj.file.filename}: {h5obj.name}"


def member(group, name: str, path: str, kind=None):
    """``group[name]``, refusing a missing member, a dangling soft link and an external link
    (a pulse file must be self-contained), and, given ``kind`` (``h5py.Group`` or
    ``h5py.Dataset``), an object of the other kind."""
    link = group.get(name, getlink=True)
    here = f"{path}: {group.name.rstrip('/')}/{name}"
    if link is None:
        raise SchemaError(f"{here}: missing")
    if isinstance(link, h5py.ExternalLink):
        raise SchemaError(f"{here} is an external link to {link.filename}:{link.path}; "
                          "slippulse files must be self-contained")
    try:
        obj = group[name]
    except (KeyError, OSError, RuntimeError):
        target = getattr(link, "path", "?")
        raise SchemaError(f"{here} is a dangling link (to {target})") from None
    if kind is not None and not isinstance(obj, kind):
        raise SchemaError(f"{here} is a {type(obj).__name__}, expected a "
                          f"{kind.__name__}")
    return obj


def real_array(ds, path: str, *, ndim: int | None = 1, min_len: int = 0, positive=False,
               allow_nan=False, complex_ok=False) -> np.ndarray:
    """The dataset as a float array: real numbers (integer or float dtype), ``ndim`` axes, at
    least ``min_len`` along the first, finite (NaN allowed with ``allow_nan``), > 0 with
    ``positive``; ``complex_ok``: complex numbers are accepted too (and returned complex)."""
    here = where(ds, path)
    if ds.dtype.kind not in ("fiuc" if complex_ok else "fiu"):
        raise SchemaError(f"{here}: dtype {ds.dtype} is not real numbers")
    if ndim is not None and ds.ndim != ndim:
        raise SchemaError(f"{here}: {ds.ndim}-D, expected {ndim}-D")
    if ds.ndim and ds.shape[0] < min_len:
        raise SchemaError(f"{here}: {ds.shape[0]} points, fewer than the {min_len} required")
    arr = np.asarray(ds[()], dtype=complex if ds.dtype.kind == "c" else float)
    bad = ~np.isfinite(arr) if not allow_nan else np.isinf(arr)
    if np.any(bad):
        raise SchemaError(f"{here}: {int(bad.sum())} value(s) not finite (NaN or inf)")
    if positive and np.any(arr <= 0):
        raise SchemaError(f"{here}: {int((arr <= 0).sum())} value(s) <= 0; must be > 0")
    return arr


def number(obj, key: str, path: str, *, lo=None, hi=None, lo_open=True, hi_open=True,
           allow_nan=False) -> float:
    """Attribute ``key`` of ``obj`` as a float: a real scalar (not a string, boolean or complex),
    finite (NaN allowed with ``allow_nan``), within the bounds given."""
    here = where(obj, path)
    if key not in obj.attrs:
        raise SchemaError(f"{here}: attribute {key!r} missing")
    raw = np.asarray(obj.attrs[key])
    if raw.shape not in ((), (1,)) or raw.dtype.kind not in "fiu":
        raise SchemaError(f"{here}: attribute {key}={obj.attrs[key]!r} is not a real number")
    val = float(raw.reshape(()))
    if math.isnan(val) and allow_nan:
        return val
    ok = math.isfinite(val)
    if ok and lo is not None:
        ok = val > lo if lo_open else val >= lo
    if ok and hi is not None:
        ok = val < hi if hi_open else val <= hi
    if not ok:
        rng = (f"{'(' if lo_open else '['}{'-inf' if lo is None else f'{lo:g}'}, "
               f"{'inf' if hi is None else f'{hi:g}'}{')' if hi_open else ']'}")
        raise SchemaError(f"{here}: attribute {key}={val!r} is out of range: must be finite "
                          f"in {rng}")
    return val


def integer(obj, key: str, path: str, *, lo=None) -> int:
    """Attribute ``key`` as an int: an integer scalar (or a float with an integral value)."""
    val = number(obj, key, path)
    if val != int(val) or (lo is not None and val < lo):
        raise SchemaError(f"{where(obj, path)}: attribute {key}={val!r} is not an integer"
                          + (f" >= {lo}" if lo is not None else ""))
    return int(val)


def boolean(obj, key: str, path: str, *, default=None) -> bool:
    """Attribute ``key`` as a bool: only a stored boolean (numpy/HDF5 bool) is one; a string such
    as "False", a number or an array is refused (``bool("False")`` is True)."""
    if key not in obj.attrs:
        if default is not None:
            return default
        raise SchemaError(f"{where(obj, path)}: attribute {key!r} missing")
    raw = obj.attrs[key]
    if isinstance(raw, (bool, np.bool_)):
        return bool(raw)
    arr = np.asarray(raw)
    if arr.dtype == np.bool_ and arr.size == 1:
        return bool(arr.reshape(()))
    raise SchemaError(f"{where(obj, path)}: attribute {key}={raw!r} is not a boolean "
                      f"({type(raw).__name__})")


def text(obj, key: str, path: str, *, choices=None, default=None) -> str:
    """Attribute ``key`` as a str (bytes decoded), one of ``choices`` when given."""
    if key not in obj.attrs:
        if default is not None:
            return default
        raise SchemaError(f"{where(obj, path)}: attribute {key!r} missing")
    raw = obj.attrs[key]
    if isinstance(raw, bytes):
        raw = raw.decode("utf-8", "replace")
    if not isinstance(raw, str) or (choices is not None and raw not in choices):
        want = f"one of {list(choices)}" if choices else "a string"
        raise SchemaError(f"{where(obj, path)}: attribute {key}={raw!r} is not {want}")
    return raw
