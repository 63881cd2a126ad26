"""Argument checks shared by the blocks, the sweep and ``reproduce``.

Every function raises a ``ValueError`` whose message names the offending
argument and says what is allowed, so that a student who mistypes a
parameter is told which one and why; :func:`install_hint` says what to install
when an optional package is missing; :func:`warn_caller` warns at the user's own line;
:func:`not_own` says why a folder is not the user's own (the fast engine's store).
"""

from __future__ import annotations

import inspect
import math
import os
import stat
import struct
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np


def install_hint(package: str, extra: str) -> str:
    """What to run when the optional ``package`` is missing: it, or controlkit's ``extra``.

    controlkit is installed from its folder (a clone), not from a package index, so an
    extra is ``pip install ".[extra]"`` run there; ``pip install "controlkit[extra]"``
    would look for controlkit on PyPI.

    Examples
    --------
    >>> install_hint("pandas", "sweep")
    'pip install pandas (or, in the folder of your controlkit clone, pip install ".[sweep]")'
    """
    shown = f'"{package}"' if "[" in package else package
    return (f'pip install {shown} (or, in the folder of your controlkit clone, '
            f'pip install ".[{extra}]")')


#: controlkit's own folder: frames there are not the user's.
_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def warn_caller(message: str, category=UserWarning) -> None:
    """:func:`warnings.warn` at the line that called into controlkit (a notebook cell, a
    script), however deep in the package the warning is raised: the line a reader can
    act on, not one of the engine's.

    Examples
    --------
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warn_caller("runs as Python")
    >>> caught[0].filename.startswith(_PACKAGE), str(caught[0].message)
    (False, 'runs as Python')
    """
    frame, level = inspect.currentframe().f_back, 2
    while frame.f_back is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)


def positive_scalar(name: str, value, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float, refusing non-finite and non-positive values.

    Examples
    --------
    >>> positive_scalar("Ts", 0.1)
    0.1
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(x) or x < 0 or (x == 0 and not allow_zero):
        allowed = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {allowed}, got {value!r}")
    return x


def in_interval(name: str, value, low: float, high: float, *, low_open: bool = True) -> float:
    """Return ``value`` as a float if it lies in ``(low, high]`` (or ``[low, high]``).

    Examples
    --------
    >>> in_interval("lambda_", 0.995, 0.0, 1.0)
    0.995
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    ok = math.isfinite(x) and (x > low if low_open else x >= low) and x <= high
    if not ok:
        bracket = "(" if low_open else "["
        raise ValueError(f"{name} must lie in {bracket}{low:g}, {high:g}], got {value!r}")
    return x


def real_scalar(name: str, value) -> float:
    """Return ``value`` as a finite float (any sign).

    Examples
    --------
    >>> real_scalar("angle_deg", -30)
    -30.0
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x


class Diverged(FloatingPointError, RuntimeError):
    """A run whose numbers became non-finite: a ``FloatingPointError``, and a
    ``RuntimeError`` as python-control raises for an interconnect whose signals do (its
    sweep of the signals cannot settle on a NaN: "algebraic loop detected"), so that
    ``except RuntimeError`` written for python-control catches it too.

    Examples
    --------
    >>> isinstance(Diverged("the loop diverged"), RuntimeError | FloatingPointError)
    True
    """


def diverged(t: float, detail: str) -> Diverged:
    """The error a block raises when the loop feeding it has diverged.

    ``detail`` says what was seen, in the block's terms. A diverged loop is
    reported as such, not as a singularity of the equation it reached. The
    error's ``time`` attribute holds ``t``, for studies that record when a run diverged.

    Examples
    --------
    >>> error = diverged(12.5, "the plant's quaternion norm is 3.1e+92")
    >>> print(error)
    the loop diverged at t = 12.5 s: the plant's quaternion norm is 3.1e+92; \
likely a gain too high for the sample time (or an unstable loop)
    >>> error.time
    12.5
    """
    error = Diverged(
        f"the loop diverged at t = {t:g} s: {detail}; likely a gain too high for the "
        f"sample time (or an unstable loop)")
    error.time = float(t)
    return error


def float_array(name: str, value) -> np.ndarray:
    """Return ``value`` as a float array, refusing text and objects by ``name``.

    numpy's own words ("could not convert string to float: 'abc'") do not say which
    argument was wrong; this message does.

    Examples
    --------
    >>> float_array("X0", [1, 0])
    array([1., 0.])
    >>> float_array("X0", ["abc", 0])
    Traceback (most recent call last):
    ...
    ValueError: X0 must be numbers, got ['abc', 0]
    """
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        raise ValueError(f"{name} must be numbers, got {shown}") from None


def vector(name: str, value, size: int) -> np.ndarray:
    """Return ``value`` as a finite float vector of length ``size``.

    Examples
    --------
    >>> vector("v1", [1, 0, 0], 3)
    array([1., 0., 0.])
    """
    x = float_array(name, value)
    if x.shape != (size,):
        raise ValueError(f"{name} must be a vector of length {size}, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite, got {x}")
    return x


def inertia(name: str, value) -> np.ndarray:
    """Return a 3x3 inertia matrix, refusing non-symmetric or non-positive-definite ones.

    A 3-vector is read as the diagonal of the matrix.

    Examples
    --------
    >>> inertia("J_b", [4000, 5000, 6000]).diagonal()
    array([4000., 5000., 6000.])
    """
    J = float_array(name, value)
    if J.shape == (3,):
        J = np.diag(J)
    if J.shape != (3, 3):
        raise ValueError(
            f"{name} must be a 3x3 inertia matrix or its diagonal (3 values), got shape {J.shape}"
        )
    if not np.all(np.isfinite(J)):
        raise ValueError(f"{name} must be finite, got {J.tolist()}")
    if not np.allclose(J, J.T, rtol=1e-12, atol=1e-12 * np.abs(J).max()):
        raise ValueError(f"{name} must be symmetric, got {J.tolist()}")
    eigenvalues = np.linalg.eigvalsh(J)
    if eigenvalues.min() <= 0:
        raise ValueError(
            f"{name} must be positive definite (all principal moments > 0), "
            f"got principal moments {eigenvalues.tolist()}"
        )
    return J


def wheel_axes(v1, v2) -> tuple[np.ndarray, np.ndarray]:
    """Return the two wheel axes as unit vectors, refusing zero or parallel axes.

    Examples
    --------
    >>> wheel_axes([2, 0, 0], [0, 1, 0])[0]
    array([1., 0., 0.])
    """
    axes = []
    for name, v in (("v1", v1), ("v2", v2)):
        v = vector(name, v, 3)
        n = np.linalg.norm(v)
        if n == 0:
            raise ValueError(f"wheel axis {name} must be a non-zero 3-vector, got {v.tolist()}")
        axes.append(v / n)
    if np.linalg.norm(np.cross(axes[0], axes[1])) < 1e-9:
        raise ValueError(
            f"wheel axes v1 and v2 must not be parallel (two wheels on one axis cannot "
            f"control two outputs), got v1={axes[0].tolist()}, v2={axes[1].tolist()}"
        )
    return axes[0], axes[1]


def momentum(name: str, value) -> Callable[[float], np.ndarray]:
    """Return an angular momentum as a function of time.

    ``value`` is a constant 3-vector or a callable ``t -> 3-vector``.

    Examples
    --------
    >>> momentum("H0", [0, 0, 0.05])(12.0)
    array([0.  , 0.  , 0.05])
    """
    if callable(value):
        probe = float_array(f"{name}(0)", value(0.0))
        if probe.shape != (3,) or not np.all(np.isfinite(probe)):
            raise ValueError(
                f"{name} must return a finite 3-vector of N m s; {name}(0) gave {probe!r}"
            )
        return value
    constant = vector(name, value, 3)
    return lambda t: constant


def gain_pair(name: str, value) -> np.ndarray:
    """Return a diagonal gain ``diag(F1, F2)`` as a length-2 vector, refusing negative entries.

    Accepts a scalar (both entries equal), two values, or a diagonal 2x2 matrix.

    Examples
    --------
    >>> gain_pair("F", 0.0009)
    array([0.0009, 0.0009])
    """
    F = float_array(name, value)
    if F.ndim == 0:
        F = np.array([float(F), float(F)])
    elif F.shape == (2, 2):
        if F[0, 1] != 0 or F[1, 0] != 0:
            raise ValueError(f"{name} must be diagonal, diag({name}1, {name}2); got {F.tolist()}")
        F = F.diagonal().copy()
    if F.shape != (2,):
        raise ValueError(f"{name} must be a scalar, two values or diag(2x2), got shape {F.shape}")
    if not np.all(np.isfinite(F)) or np.any(F < 0):
        raise ValueError(f"{name} must be finite and >= 0 (a negative gain destabilises), got {F}")
    return F


def gain_matrix(name: str, value) -> np.ndarray:
    """Return a 2x2 compensation gain, accepting a scalar (times identity) or a 2x2 matrix.

    Examples
    --------
    >>> gain_matrix("K", 0.1)
    array([[0.1, 0. ],
           [0. , 0.1]])
    """
    try:
        K = np.asarray(value, dtype=float)
    except (TypeError, ValueError):  # the message says what shapes are allowed, too
        raise ValueError(f"{name} must be a number or a 2x2 matrix of numbers, "
                         f"got {value!r}") from None
    if K.ndim == 0:
        K = float(K) * np.eye(2)
    if K.shape != (2, 2):
        raise ValueError(f"{name} must be a scalar or a 2x2 matrix, got shape {K.shape}")
    if not np.all(np.isfinite(K)):
        raise ValueError(f"{name} must be finite, got {K.tolist()}")
    return K


def unit_quaternion(name: str, value, tol: float = 1e-6) -> np.ndarray:
    """Return a unit quaternion ``[q0, q1, q2, q3]`` (scalar first).

    controlkit refuses, rather than silently normalises, a quaternion whose
    norm differs from 1 by more than ``tol``: a non-unit attitude is almost
    always a typing or unit mistake worth seeing. Within ``tol`` the vector is
    normalised so that the simulation starts on the unit sphere exactly.

    Examples
    --------
    >>> unit_quaternion("q", [1, 0, 0, 0])
    array([1., 0., 0., 0.])
    """
    q = vector(name, value, 4)
    n = np.linalg.norm(q)
    if abs(n - 1.0) > tol:
        raise ValueError(
            f"{name} must be a unit quaternion [q0, q1, q2, q3] (norm 1 within {tol:g}), "
            f"got norm {n:.9g}; build one with quaternion_from_axis_angle(axis, angle)"
        )
    return q / n


def folder(name: str, path) -> Path:
    """``path`` as a folder to write into (``~`` expanded), refused before anything is
    created when it is empty (it would mean the current folder), a file, or under a file
    or a place that cannot be written.

    Examples
    --------
    >>> folder("out", "~/results").name
    'results'
    >>> folder("out", " ")
    Traceback (most recent call last):
    ...
    ValueError: out must name a folder, got ' '
    """
    if not isinstance(path, str | os.PathLike):
        raise ValueError(f"{name} must be a folder path, got {path!r}")
    if not str(os.fspath(path)).strip():
        raise ValueError(f"{name} must name a folder, got {path!r}")
    found = Path(path).expanduser()  # "~/results" means the home folder, as in a shell
    if found.exists() and not found.is_dir():
        raise ValueError(f"{name} {str(found)!r} is a file, not a folder")
    existing = found.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"cannot write to {name} {str(found)!r}: {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"cannot write to {name} {str(found)!r}: {existing} is not writable")
    return found


def not_own(path: Path) -> str | None:
    """Why ``path`` is not the user's own folder (None when it is).

    It must be a folder, not a link, owned by the user and writable by nobody else, by
    its mode or by an access control list, nor give what is made in it to others by a
    default list (the user's private group, named as the user, allowed, as a umask of 002
    leaves folders);
    every folder above it owned by the user or root and not writable by others unless
    sticky (as ``/tmp``), so that nobody else can rename it away; and every link on the
    way owned by the user or root, in such a folder, so that nobody else can point it
    elsewhere.

    Examples
    --------
    >>> import tempfile
    >>> shared = Path(tempfile.mkdtemp())
    >>> shared.chmod(0o777)
    >>> not_own(shared).endswith("can be written by others (mode 777)")
    True
    """
    if not hasattr(os, "getuid"):  # Windows: the profile folder's ACLs decide
        return None
    uid = os.getuid()
    path = Path(os.path.abspath(path))
    info = os.lstat(path)
    if stat.S_ISLNK(info.st_mode):
        return f"{path} is a link (give the folder itself)"
    if not stat.S_ISDIR(info.st_mode):
        return f"{path} is not a folder"
    if info.st_uid != uid:
        return f"{path} is owned by another user (uid {info.st_uid})"
    if _writable_by_others(info):
        return f"{path} can be written by others (mode {stat.S_IMODE(info.st_mode):o})"
    for acl, what in ((ACCESS_ACL, "can be written by others"),
                      (DEFAULT_ACL, "gives what is made in it to others to write")):
        if _acl_lets_others_write(path, acl):
            return f"{path} {what} (an access control list: getfacl {path})"
    # every link on the written path, and every folder above the folder it leads to
    for prefix in list(path.parents)[::-1]:
        link = os.lstat(prefix)
        if stat.S_ISLNK(link.st_mode) and link.st_uid not in (uid, 0):
            return f"{prefix} is a link owned by another user (uid {link.st_uid})"
    for parent in Path(os.path.realpath(path)).parents:
        info = os.stat(parent)
        if info.st_uid not in (uid, 0):
            return f"{parent} is owned by another user (uid {info.st_uid})"
        if info.st_mode & stat.S_ISVTX:
            continue
        if _writable_by_others(info):
            return (f"{parent} can be written by others (mode "
                    f"{stat.S_IMODE(info.st_mode):o}), who could replace the folder")
        if _acl_lets_others_write(parent, ACCESS_ACL):
            return (f"{parent} can be written by others (an access control list: getfacl "
                    f"{parent}), who could replace the folder")
    return None


def numba_cache_not_own() -> str | None:
    """Why numba's cache folder is not the user's own (:func:`not_own`), None when it is or
    when none is set: as numba last read it (``NUMBA_CACHE_DIR``, or a
    ``.numba_config.yaml`` in the current folder; read again at each compile), else the
    variable. A folder not there yet is made now, the user's: numba would make it after
    the check.

    Examples
    --------
    >>> numba_cache_not_own() is None or "numba's cache folder" in numba_cache_not_own()
    True
    """
    config = getattr(sys.modules.get("numba"), "config", None)
    cache = getattr(config, "CACHE_DIR", None) or os.environ.get("NUMBA_CACHE_DIR", "")
    if not cache:
        return None
    folder = Path(os.path.abspath(cache))
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        why = not_own(folder)
    except OSError as error:
        why = f"it cannot be created ({error.strerror or error})"
    return why and f"numba's cache folder {folder}: {why}"


#: The extended attributes holding a folder's POSIX access control lists (acl(5)): the
#: one in force, and the default that what is made in the folder inherits.
ACCESS_ACL, DEFAULT_ACL = "system.posix_acl_access", "system.posix_acl_default"


def _acl_lets_others_write(path, attribute) -> bool:
    """Whether the POSIX access control list ``attribute`` of ``path`` lets another user
    or a group write (an entry with ``w`` within the list's mask). A folder's mode shows
    only the mask in its group bits, so a list can let others write where the mode seems
    the user's own. The attribute is Linux's (a version, then entries of tag, permissions
    and id: ``linux/posix_acl_xattr.h``); none there, or no such attributes, is no list.
    A default list counts its owning group and others too: they are what new folders get.
    """
    try:
        data = os.getxattr(path, attribute, follow_symlinks=False)
    except (AttributeError, OSError):
        return False
    entries = [struct.unpack_from("<HHI", data, offset) for offset in range(4, len(data) - 7, 8)]
    mask = next((perm for tag, perm, _ in entries if tag == _ACL_MASK), 0o7)
    others = (_ACL_USER, _ACL_GROUP) + (
        (_ACL_GROUP_OBJ, _ACL_OTHER) if attribute == DEFAULT_ACL else ())
    return any(tag in others and perm & 0o2 and (tag == _ACL_OTHER or perm & mask & 0o2)
               and not (tag == _ACL_USER and qualifier == os.getuid())
               for tag, perm, qualifier in entries)


_ACL_USER, _ACL_GROUP_OBJ, _ACL_GROUP, _ACL_MASK, _ACL_OTHER = 0x02, 0x04, 0x08, 0x10, 0x20


def _writable_by_others(info) -> bool:
    if info.st_mode & stat.S_IWOTH:
        return True
    if not info.st_mode & stat.S_IWGRP:
        return False
    try:  # the user's private group (umask 002) is not "others": named as the user, of no
        import grp  # other member (a shared primary group, "users", also lists none)
        import pwd

        group = grp.getgrgid(info.st_gid)
        mine = group.gr_name == pwd.getpwuid(os.getuid()).pw_name
        return not (info.st_gid == os.getgid() and mine and not group.gr_mem)
    except (ImportError, KeyError):
        return True
