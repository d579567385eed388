"""Self-describing HDF5 files for steady pulses (schema of the steady-solver issue).

Layout::

    /                      attrs: slippulse_version, created
    /parameters            attrs: mu, sigma, c_s, D, b, v_star, f0, phi_star, alpha (SI) + units
    /pulses/td1.2000       datasets xi (m), v (m/s), phi (s), tau (Pa), residual (1)
                           attrs tau_d_ratio, tau_d, tau_min, beta, c_p, L, L_tilde, v_stick, v_max,
                           max_residual, converged, n_points, wall_time, mode, status, message

Format version 2 (root attributes ``format = "slippulse-steady"``, ``format_version = 2``): ``xi``
of each pulse group is an HDF5 dimension scale (dimension ``xi``) attached to v, phi, tau and
residual, and every dataset carries ``units`` and ``long_name``, so that
``xarray.open_datatree(path, engine="h5netcdf")`` reads the file with named dimensions and
coordinates (netCDF-4 conventions). Version 1 files (no ``format_version``: the same datasets
without dimension scales) are read as well, and are upgraded in place when a pulse is added to
them; files of a newer version are refused with a message naming it. Groups and datasets that the
schema does not name (e.g. a ``spectrum`` subgroup of a pulse group) are left alone.

The helpers :func:`coordinate`, :func:`dimension` and :func:`describe` give the other writers
(dynamics.runfile, timedomain.verify, timedomain.scan, steady analysis) the same conventions.

Every access holds the file's lock (:mod:`.locking`). An update of an existing file
(:func:`atomic_update`) is built in memory and committed through a journal (:mod:`.journal`),
costing the bytes it changes; a file written whole is built in memory and replaces the target
with ``os.replace`` (:mod:`.atomic`). HDF5 never writes to the disk itself, so a full disk is an
ordinary ``OSError`` and leaves the previous file intact.
"""
from __future__ import annotations

import datetime as _dt
import io
import os
import tempfile
from dataclasses import dataclass, field

import h5py
import numpy as np

from .. import __version__
from . import validate
from .atomic import named_errors, read_only, remove_stale_temporaries, replacing
from .errors import SchemaError
from .journal import JournaledFile, recover
from .locking import file_lock
from .params import Parameters

#: Version of the file layouts written by this code (root attribute ``format_version``).
FORMAT_VERSION = 2
PARAM_NAMES = ("mu", "sigma", "c_s", "D", "b", "v_star", "f0", "phi_star", "alpha")
DATASETS = {"xi": "m", "v": "m/s", "phi": "s", "tau": "Pa", "residual": "1"}
LONG_NAMES = {"xi": "co-moving coordinate xi = x - c_p t (pulse moves toward +xi)",
              "v": "slip rate", "phi": "state variable", "tau": "shear stress",
              "residual": "residual of the steady equations (Delta)"}
ATTRS = {
    "tau_d_ratio": "1", "tau_d": "Pa", "tau_min": "Pa", "beta": "1", "c_p": "m/s", "L": "m",
    "L_tilde": "1", "v_stick": "m/s", "v_max": "m/s", "max_residual": "1", "converged": "bool",
    "n_points": "1", "wall_time": "s", "mode": "str",
}


class UnconvergedPulseError(SchemaError):
    """A pulse marked ``converged = False`` where a converged one is needed (exit code 2)."""


class PulseExistsError(SchemaError):
    """A pulse label already present in the output file (replaced only when asked to, and a
    converged pulse never by an unconverged one)."""


#: netCDF-4 marker of a dimension scale that is not a variable (``NAME`` attribute prefix).
_DIM_ONLY = "This is a netCDF dimension but not a netCDF variable."


def stamp_format(h5, kind: str) -> None:
    """Mark a file (or its root group) as slippulse ``kind`` in the current format version."""
    h5.attrs["format"] = f"slippulse-{kind}"
    h5.attrs["format_version"] = np.int64(FORMAT_VERSION)


def format_version(h5, path: str = "") -> int:
    """Layout version of an open file: ``format_version`` (1 when absent, the layout before it).

    Raises :class:`SchemaError` naming the version when it is not 1..FORMAT_VERSION.
    """
    raw = h5.attrs.get("format_version", 1)
    try:
        ver = int(np.asarray(raw).item())
    except (TypeError, ValueError):
        raise SchemaError(f"{path or h5.filename}: format_version={raw!r} is not an integer") from None
    if ver > FORMAT_VERSION:
        raise SchemaError(f"{path or h5.filename}: format_version {ver} is newer than this "
                          f"slippulse {__version__} reads (1 to {FORMAT_VERSION}); upgrade slippulse")
    if ver < 1:
        raise SchemaError(f"{path or h5.filename}: format_version {ver} is not a slippulse layout "
                          f"(1 to {FORMAT_VERSION})")
    return ver


def describe(ds, units: str, long_name: str, dims=()) -> "h5py.Dataset":
    """Set ``units`` and ``long_name`` of ``ds`` and attach the dimension scales ``dims`` (one per
    axis, in order; :func:`coordinate` or :func:`dimension` datasets). Returns ``ds``."""
    ds.attrs["units"] = units
    ds.attrs["long_name"] = long_name
    for axis, scale in enumerate(dims):
        ds.dims[axis].attach_scale(scale)
    return ds


def coordinate(group, name: str, data=None, *, units: str, long_name: str, unlimited=False,
               dtype="f8", chunks=None) -> "h5py.Dataset":
    """A 1-D coordinate variable ``group/name``: an HDF5 dimension scale of dimension ``name``.

    ``unlimited``: created empty (or from ``data``) with ``maxshape=(None,)``, to be resized as a
    time axis grows.
    """
    if unlimited:
        n = 0 if data is None else len(data)
        ds = group.create_dataset(name, shape=(n,), maxshape=(None,), dtype=dtype,
                                  chunks=chunks or (1024,))
        if n:
            ds[...] = data
    else:
        ds = group.create_dataset(name, data=data, dtype=dtype)
    ds.make_scale(name)
    return describe(ds, units, long_name)


def dimension(group, name: str, size: int) -> "h5py.Dataset":
    """A dimension without a coordinate variable (netCDF-4 convention: a dimension scale whose
    ``NAME`` says so; xarray lists it under "Dimensions without coordinates")."""
    ds = group.create_dataset(name, shape=(size,), dtype="f4")
    ds.make_scale(f"{_DIM_ONLY}{size:10d}")
    return ds


def _attach_pulse_scales(grp) -> None:
    """Make ``xi`` of a pulse group a dimension scale and attach it to the other datasets
    (idempotent: a version-1 group is upgraded, a version-2 group left as it is)."""
    xi = grp["xi"]
    if not xi.is_scale:
        xi.make_scale("xi")
    for name in DATASETS:
        ds = grp[name]
        if "long_name" not in ds.attrs:
            ds.attrs["long_name"] = LONG_NAMES[name]
        if name != "xi" and ds.ndim == 1 and len(ds.dims[0]) == 0:
            ds.dims[0].attach_scale(xi)


def upgrade_steady(h5) -> None:
    """Bring an open steady/family file to the current format (dimension scales on every pulse
    group that has the schema's datasets); other groups and subgroups are left alone. A file
    stamped current is left as it is: every writer of this version writes its groups in the
    current format (the walk over all pulses made each write of a family cost O(pulses))."""
    if (format_version(h5) == FORMAT_VERSION
            and str(h5.attrs.get("format", "")) == "slippulse-steady"):
        return
    for grp in (h5["pulses"].values() if "pulses" in h5 else ()):
        if isinstance(grp, h5py.Group) and all(n in grp for n in DATASETS):
            _attach_pulse_scales(grp)
    stamp_format(h5, "steady")


#: Order of the steady state integrator: the steady solver's default, and the order of every pulse
#: written with the fourth-order integrator (stored as the pulse attribute ``state_order``).
STATE_ORDER = 4
#: Order of a stored pulse whose file has no ``state_order`` attribute (written by the earlier
#: second-order integrator).
UNSTORED_STATE_ORDER = 2


def state_order_of(pulse) -> int:
    """State-integrator order a pulse was solved with: its ``state_order`` attribute, or
    :data:`UNSTORED_STATE_ORDER` when its file predates that attribute. Raises ValueError or
    TypeError for an attribute that is not an integer."""
    return int(pulse.extra.get("state_order", UNSTORED_STATE_ORDER))


def pulse_label(tau_d_ratio: float) -> str:
    """Group name of a pulse: 'td' + τ_d/τ_min with 4 decimals when it is round to them within
    5e-7 (e.g. td1.2000; a grid check's refined pulse may lie 1e-7 off its target), else with 6
    (e.g. td1.009074, a step of the deep march or of β)."""
    if abs(tau_d_ratio - round(tau_d_ratio, 4)) <= 5e-7:
        return f"td{tau_d_ratio:.4f}"
    return f"td{tau_d_ratio:.6f}"


#: Most decimals a label takes (:func:`unique_label`): 1e-10 in τ_d/τ_min, below the τ_d within
#: which two pulses are the same one (:data:`SAME_PULSE_RATIO`).
MAX_LABEL_DECIMALS = 10
#: Two pulses whose τ_d/τ_min differ by no more than this are the same pulse (a re-solve, or a
#: resumed march writing it again); the deep march's smallest τ_d steps are ~1e-8.
SAME_PULSE_RATIO = 1e-9


def unique_label(tau_d_ratio: float, taken: dict) -> str:
    """Label of a new pulse at ``tau_d_ratio`` in a file whose labels are ``taken`` (label → τ_d/τ_min
    of the pulse stored there): :func:`pulse_label` unless a pulse at another τ_d holds it (deep
    steps closer than 1e-6), then the fewest decimals beyond 6 that are free or hold
    the same τ_d (within :data:`SAME_PULSE_RATIO`). ValueError when none up to
    :data:`MAX_LABEL_DECIMALS` is."""
    def free(lab):
        q = taken.get(lab)
        return q is None or abs(q - tau_d_ratio) <= SAME_PULSE_RATIO
    lab = pulse_label(tau_d_ratio)
    if free(lab):
        return lab
    for d in range(7, MAX_LABEL_DECIMALS + 1):
        lab = f"td{tau_d_ratio:.{d}f}"
        if free(lab):
            return lab
    raise ValueError(f"no free label for tau_d/tau_min={tau_d_ratio!r}: a pulse is stored within "
                     f"{SAME_PULSE_RATIO:g} of it")


def label_decimals(label: str) -> int:
    """Decimals of a label's number ('td1.2000' → 4, 'td1.0085716' → 7; 0 without a point)."""
    return len(label.split(".", 1)[1]) if "." in label else 0


def label_ratio(label) -> float:
    """τ_d/τ_min of a pulse label, the inverse of :func:`pulse_label` ('td1.2000' → 1.2,
    'td1.009074' → 1.009074); NaN for a name that is not 'td' followed by a number. The one
    parser of pulse labels: every reader calls it."""
    if not isinstance(label, str) or not label.startswith("td"):
        return float("nan")
    try:
        return float(label[2:])
    except ValueError:
        return float("nan")


@dataclass
class Pulse:
    """A steady pulse on its grid. ξ ascending, the pulse travels toward +ξ (rest state at large ξ)."""

    xi: np.ndarray
    v: np.ndarray
    phi: np.ndarray
    tau: np.ndarray
    residual: np.ndarray
    tau_d_ratio: float
    tau_d: float
    tau_min: float
    beta: float
    c_p: float
    L: float
    L_tilde: float
    v_stick: float
    v_max: float
    max_residual: float
    converged: bool
    n_points: int
    wall_time: float
    mode: str = "III"
    extra: dict = field(default_factory=dict)
    #: the group name it is stored (or to be stored) under, when that is not :func:`pulse_label`
    #: (a longer label that keeps two close deep pulses apart, :func:`unique_label`); set by
    #: :func:`read_pulse`. Ignored once it no longer names this τ_d (a copy re-solved elsewhere).
    name: str = ""

    @property
    def label(self) -> str:
        if self.name:
            q = label_ratio(self.name)
            if abs(q - self.tau_d_ratio) <= 0.5 * 10.0 ** -label_decimals(self.name) + 5e-7:
                return self.name
        return pulse_label(self.tau_d_ratio)


def atomic_update(path: str, fill, replace: bool = False) -> None:
    """Apply ``fill(h5file)`` to `path` under its lock: the one way a slippulse HDF5 file is
    written.

    An existing file is updated in place through a journal (:mod:`.journal`): the cost is the
    bytes changed, and a kill or a full disk leaves it as it was or completes the update on the
    next open. ``replace`` (or a new file): the content is built in memory and replaces `path`
    atomically. An existing `path` that is not a readable HDF5 file is refused
    (:class:`SchemaError` naming it) unless ``replace``; a read-only one is refused
    (``PermissionError`` naming it) before anything is written.
    """
    shown = path
    path = os.path.abspath(path)
    d = os.path.dirname(path)
    if os.path.exists(d) and not os.path.isdir(d):
        raise SchemaError(f"{shown}: cannot write there, {d} is a file, not a directory")
    os.makedirs(d, exist_ok=True)
    with named_errors(shown), file_lock(path):
        recover(path)
        remove_stale_temporaries(path)
        exists = os.path.exists(path)
        if exists and read_only(path):
            raise PermissionError(13, "file is not writable (read-only)", shown)
        if exists and not replace:
            with open_h5(shown, "output"):     # an existing target must be a readable HDF5 file
                pass
            jf = JournaledFile(path)
            try:
                with h5py.File(jf, "r+") as h5:
                    fill(h5)
            except BaseException:
                jf.close()
                raise
            jf.commit()
            return
        buf = io.BytesIO()
        with h5py.File(buf, "w") as h5:
            h5.attrs["slippulse_version"] = __version__
            h5.attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat()
            fill(h5)
        with replacing(path, suffix=".h5") as tmp:
            with open(tmp, "wb") as fh:
                fh.write(buf.getbuffer())


def write_parameters(h5: h5py.File, params: Parameters) -> None:
    grp = h5.require_group("parameters")
    for name in PARAM_NAMES:
        grp.attrs[name] = float(getattr(params, name))
        grp.attrs[f"{name}_units"] = Parameters.UNITS[name]


def read_parameters(h5: h5py.File, path: str = "") -> Parameters:
    """The Table-I parameters of an open file, checked (real, finite, in range, N-shaped law)."""
    path = path or h5.filename
    grp = validate.member(h5, "parameters", path, h5py.Group)
    vals = {n: validate.number(grp, n, path) for n in PARAM_NAMES}
    try:
        return Parameters(**vals)
    except (TypeError, ValueError) as exc:          # ParameterError included
        raise SchemaError(f"{path}: /parameters: {exc}") from None


def write_pulse(path: str, pulse: Pulse, params: Parameters, overwrite: bool = True) -> None:
    """Add (or replace) `pulse` as ``pulses/<label>`` in `path`, atomically.

    A pulse already stored under the label is replaced only with ``overwrite``; a converged one is
    never replaced by an unconverged `pulse` (:class:`PulseExistsError` in both cases, the file
    unchanged).
    """
    atomic_update(path, lambda h5: _put_pulses(h5, path, [pulse], params, overwrite))


def write_pulses(path: str, pulses, params: Parameters, replace: bool = False) -> None:
    """Write several pulses in one :func:`atomic_update` under `path`'s own lock: all of them or
    none (:func:`write_pulse`'s rules for each); ``replace``: they replace the file's content.
    Why: a command that writes what it found as one result (``steady branches``) must not leave
    part of it, nor a temporary file beside `path`, when killed or refused."""
    pulses = list(pulses)
    atomic_update(path, lambda h5: _put_pulses(h5, path, pulses, params, True), replace=replace)


def _put_pulses(h5, path: str, pulses, params: Parameters, overwrite: bool) -> None:
    """:func:`write_pulse`'s content for each of ``pulses``, into the open file ``h5``: the
    file's format, parameters and existing pulses checked once, then each pulse written."""
    format_version(h5, path)
    if "parameters" in h5:
        old = read_parameters(h5, path)
        if old != params:
            from .params import describe_difference
            raise SchemaError(f"{path}: stored parameters differ from this run's: "
                              + describe_difference(old, params, "stored", "this run"))
    else:
        write_parameters(h5, params)
    if h5.get("pulses", getlink=True) is not None:
        _labels(h5, path)                  # refuse to add to a file whose pulses are broken
    group = h5.require_group("pulses")
    for pulse in pulses:
        _put_pulse(group, path, pulse, overwrite)
    upgrade_steady(h5)


def _put_pulse(pulses, path: str, pulse: Pulse, overwrite: bool) -> None:
    """One pulse into the file's ``pulses`` group, under :func:`write_pulse`'s rules."""
    if pulse.label in pulses:
        if not pulse.converged and pulse_converged(pulses[pulse.label], path):
            raise PulseExistsError(f"{path}: pulse {pulse.label} is stored converged; an "
                                   "unconverged solve never replaces it (kept unchanged)")
        if not overwrite:
            raise PulseExistsError(f"{path}: pulse {pulse.label} already present (replace "
                                   "it with --overwrite)")
        del pulses[pulse.label]
    grp = pulses.create_group(pulse.label)
    xi = coordinate(grp, "xi", np.asarray(pulse.xi, dtype=float), units=DATASETS["xi"],
                    long_name=LONG_NAMES["xi"])
    for name, unit in DATASETS.items():
        if name != "xi":
            describe(grp.create_dataset(name, data=np.asarray(getattr(pulse, name), dtype=float)),
                     unit, LONG_NAMES[name], dims=(xi,))
    for name in ATTRS:
        val = getattr(pulse, name)
        grp.attrs[name] = np.bool_(val) if name == "converged" else val
    for key, val in pulse.extra.items():
        grp.attrs[key] = val


#: Fewest grid points a stored pulse may have (a resolved pulse has hundreds; fewer is a
#: truncated or foreign file, on which the readers' interpolation and seeding would fail).
MIN_PULSE_POINTS = 16
#: Relative agreement required between τ_d and τ_d_ratio·τ_min of a stored pulse.
TAU_D_RTOL = 1e-6
#: Attribute ranges of a pulse: (low, high), open at both ends; None: unbounded.
_ATTR_RANGES = {"tau_d_ratio": (0.0, None), "tau_d": (0.0, None), "tau_min": (0.0, None),
                "beta": (0.0, 1.0), "c_p": (0.0, None), "L": (0.0, None),
                "L_tilde": (0.0, None), "v_stick": (0.0, None), "v_max": (0.0, None),
                "max_residual": (None, None), "wall_time": (None, None)}


def _group_to_pulse(grp, path: str = "") -> Pulse:
    """The validating reader of one pulse group: every check of :mod:`.validate` (datasets of
    finite reals, v > 0 and φ > 0, ξ ascending, at least :data:`MIN_PULSE_POINTS` points;
    attributes of the right type and range, 0 < β < 1, ``converged`` a stored boolean, the
    label agreeing with τ_d/τ_min, τ_d = τ_d_ratio·τ_min). One :class:`SchemaError` naming the
    file and the group otherwise."""
    path = path or grp.file.filename
    here = validate.where(grp, path)
    arrays = {}
    for name in DATASETS:
        ds = validate.member(grp, name, path, h5py.Dataset)
        arrays[name] = validate.real_array(ds, path, min_len=MIN_PULSE_POINTS,
                                           positive=name in ("v", "phi"))
    xi = arrays["xi"]
    n = xi.size
    if any(a.shape != (n,) for a in arrays.values()):
        raise SchemaError(f"{here}: datasets must be 1-D of equal length "
                          f"({ {k: a.shape[0] for k, a in arrays.items()} })")
    if np.any(np.diff(xi) <= 0):
        raise SchemaError(f"{here}: xi must be strictly ascending")
    kw = {}
    for name, (lo, hi) in _ATTR_RANGES.items():
        kw[name] = validate.number(grp, name, path, lo=lo, hi=hi,
                                   allow_nan=name in ("wall_time", "max_residual"))
    kw["converged"] = validate.boolean(grp, "converged", path)
    kw["n_points"] = validate.integer(grp, "n_points", path, lo=0)
    kw["mode"] = validate.text(grp, "mode", path, choices=("III", "II"))
    label = grp.name.rsplit("/", 1)[-1]
    q = label_ratio(label)
    tol = 0.5 * 10.0 ** -label_decimals(label) + 5e-7
    if not abs(q - kw["tau_d_ratio"]) <= tol:
        raise SchemaError(f"{here}: the label says tau_d/tau_min={q:g} but the attribute "
                          f"tau_d_ratio={kw['tau_d_ratio']!r}")
    if not abs(kw["tau_d"] - kw["tau_d_ratio"] * kw["tau_min"]) <= TAU_D_RTOL * kw["tau_d"]:
        raise SchemaError(f"{here}: tau_d={kw['tau_d']!r} Pa disagrees with tau_d_ratio*tau_min="
                          f"{kw['tau_d_ratio'] * kw['tau_min']!r} Pa")
    extra = {k: grp.attrs[k] for k in grp.attrs if k not in ATTRS}
    return Pulse(**arrays, **kw, extra=extra, name=label)


class LockedFile(h5py.File):
    """An HDF5 file opened read-only that holds its lock (:mod:`.locking`) until closed."""

    _release = None

    def close(self):
        try:
            if self.id.valid:
                super().close()
        finally:
            rel, self._release = self._release, None
            if rel is not None:
                rel.__exit__(None, None, None)


def open_h5(path: str, what: str = "file") -> h5py.File:
    """Open ``path`` read-only, holding its lock until the file is closed (first completing or
    discarding an update a kill interrupted, :func:`.journal.recover`); a missing, empty,
    truncated or non-HDF5 file raises :class:`SchemaError` naming it (``what``: the parameter
    it came from, for the message)."""
    if os.path.isdir(path):
        raise SchemaError(f"{what}={path!r} is a directory, not a file")
    if not os.path.isfile(path):
        raise SchemaError(f"{what}={path!r}: no such file")
    if not os.access(path, os.R_OK):
        raise SchemaError(f"{what}={path!r}: not readable (permission denied)")
    cm = file_lock(path, required=False)
    cm.__enter__()
    try:
        recover(path)
        if os.path.getsize(path) == 0:
            raise SchemaError(f"{what}={path!r}: empty file (0 bytes), not HDF5")
        try:
            h5 = LockedFile(path, "r")
        except OSError as exc:
            text = str(exc)
            if "lock" in text.lower():
                raise SchemaError(f"{what}={path!r}: open for writing by another program "
                                  "(HDF5 file lock); retry when it has finished") from None
            reason = text.split("(")[0].strip().rstrip(",")
            raise SchemaError(f"{what}={path!r}: not a readable HDF5 file ({reason}; "
                              "truncated, or not HDF5)") from None
    except BaseException:
        cm.__exit__(None, None, None)
        raise
    h5._release = cm
    return h5


def check_writable(path: str, what: str = "out") -> None:
    """Refuse (:class:`SchemaError`), before any work is done, an output path that could not be
    written: its nearest existing parent is not a directory, or no file can be created there (a
    trial file is created and removed), or it names an existing directory or read-only file,
    or it is empty or ends in a path separator (a directory meant, not a file)."""
    if not isinstance(path, str) or not path.strip():
        raise SchemaError(f"{what}={path!r} is empty; give a file name")
    if path.endswith((os.sep, "/")) or (os.altsep and path.endswith(os.altsep)):
        raise SchemaError(f"{what}={path!r} ends in a path separator; give a file name "
                          f"(e.g. {os.path.join(path, 'out.h5')})")
    full = os.path.abspath(path)
    d = os.path.dirname(full)
    while not os.path.exists(d):
        d = os.path.dirname(d)
    if not os.path.isdir(d):
        raise SchemaError(f"{what}={path!r}: cannot write there, {d} is a file, not a directory")
    if os.path.isdir(full):
        raise SchemaError(f"{what}={path!r} is a directory; give a file name")
    if os.path.exists(full) and read_only(full):
        raise SchemaError(f"{what}={path!r}: the existing file is not writable")
    try:
        fd, trial = tempfile.mkstemp(prefix=".tmp-probe-", dir=d)
    except OSError as exc:
        raise SchemaError(f"{what}={path!r}: cannot write in {d} ({exc.strerror})") from None
    os.close(fd)
    os.remove(trial)


def _labels(h5, path: str) -> list[str]:
    """Pulse labels of an open file, sorted by decreasing τ_d; anything else in ``pulses`` (a
    name that is not tdX.XXXX, a dataset, a dangling or external link) is an error naming it."""
    format_version(h5, path)
    if h5.get("pulses", getlink=True) is None:
        raise SchemaError(f"{path}: no 'pulses' group (not a slippulse steady/family file)")
    pulses = validate.member(h5, "pulses", path, h5py.Group)
    labels = list(pulses.keys())
    ratios = []
    for lab in labels:
        ratios.append(label_ratio(lab))
        if not np.isfinite(ratios[-1]):
            raise SchemaError(f"{path}: /pulses/{lab} is not a pulse label (expected tdX.XXXX)")
        validate.member(pulses, lab, path, h5py.Group)
    return [lab for _, lab in sorted(zip(ratios, labels), key=lambda p: -p[0])]


def labels_in(h5, path: str) -> list[str]:
    """Pulse labels of an open file by decreasing τ_d, each a group that resolves inside the
    file (the public name of the check every reader of a family makes)."""
    return _labels(h5, path)


def check_pulse_group(grp, path: str) -> Pulse:
    """The validating reader of one open pulse group (:func:`read_pulse` without opening)."""
    return _group_to_pulse(grp, path)


def check_pulses(path: str, what: str = "FILE") -> list[str]:
    """Validate a whole steady/family file before a command works on it: its parameters and
    every pulse group (:func:`check_pulse_group`). Returns the labels (decreasing τ_d); the first
    problem raises :class:`SchemaError` naming the file and the group."""
    with open_h5(path, what) as h5:
        labels = _labels(h5, path)
        read_parameters(h5, path)
        for lab in labels:
            _group_to_pulse(h5["pulses"][lab], path)
    return labels


def list_pulses(path: str) -> list[str]:
    """Labels of the pulses in a file, sorted by decreasing τ_d."""
    with open_h5(path) as h5:
        return _labels(h5, path)


def read_pulse(path: str, label: str | None = None) -> tuple[Pulse, Parameters]:
    """Read one pulse (the only one, or `label`) and the parameters it was computed with.

    Reads format versions 1 and 2; any file that does not follow the schema raises
    :class:`SchemaError` with a one-line message naming the file (and the label).
    """
    with open_h5(path) as h5:
        labels = _labels(h5, path)
        params = read_parameters(h5, path)
        if label is None:
            if len(labels) != 1:
                raise SchemaError(f"{path}: holds {len(labels)} pulses, name one with --label "
                                  f"(one of {labels})")
            label = labels[0]
        if label not in labels:
            raise SchemaError(f"{path}: no pulse label={label!r}; present: {labels}")
        return _group_to_pulse(h5["pulses"][label], path), params


def pulse_converged(grp, path: str = "") -> bool:
    """The ``converged`` attribute of a pulse group: a stored boolean, else :class:`SchemaError`
    (a string "False" is not False, and is not taken as True either)."""
    return validate.boolean(grp, "converged", path or grp.file.filename)


def stored_converged(path: str, label: str) -> bool | None:
    """Whether ``path`` holds pulse ``label`` and it is marked converged (None: no such pulse or
    no such file)."""
    if not os.path.isfile(path):
        return None
    with open_h5(path) as h5:
        if label not in _labels(h5, path):
            return None
        return pulse_converged(h5["pulses"][label], path)


def require_converged(path: str, labels=None, *, allow: bool = False, hint: str = "") -> list[str]:
    """The check every reader of steady pulses makes before using them: the pulses ``labels`` of
    ``path`` (default: all) must be marked ``converged = True``.

    Parameters
    ----------
    path : steady/family HDF5 file.
    labels : iterable of str, optional
        Pulses the command will use (labels absent from the file are left to the reader).
    allow : bool
        Return the unconverged labels instead of raising (the caller marks its output).
    hint : str
        Appended to the message (e.g. the option that allows or skips them).

    Returns
    -------
    list of str
        The unconverged labels among ``labels`` (empty unless ``allow``).

    Raises
    ------
    UnconvergedPulseError
        One line naming the file and the label(s), when some pulse is unconverged and not ``allow``.
    """
    with open_h5(path) as h5:
        present = _labels(h5, path)
        wanted = present if labels is None else [lab for lab in labels if lab in present]
        bad = [lab for lab in wanted if not pulse_converged(h5["pulses"][lab], path)]
    if bad and not allow:
        names = ", ".join(bad[:4]) + (f" and {len(bad) - 4} more" if len(bad) > 4 else "")
        msg = (f"{path}: pulse{'s' if len(bad) > 1 else ''} {names} "
               f"{'are' if len(bad) > 1 else 'is'} marked converged=False (the solve failed); "
               "refused")
        raise UnconvergedPulseError(msg + (f" ({hint})" if hint else ""))
    return bad
