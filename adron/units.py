"""Physical quantities written with units ("30 cm", "1.8 kgf*cm", "60 rpm") -> SI floats.

Every value that reaches parmor from a file or the command line carries its unit; inside,
everything is an SI float (metres, kilograms, seconds, radians, ...). A bare number is
refused for any dimension but ``dimensionless``: "30" for a length could be millimetres or
centimetres, and guessing wrong builds the wrong robot.

The unit text is read by a small strict grammar of our own (``name[exponent]`` factors
joined by ``*``, ``·``, ``/`` or a space; exponents as ``**2``, ``^2``, ``²`` or the ``cm2``
shorthand for 2 and 3); pint only looks up single unit names and converts. That keeps
pint's lenient expression parser (which reads "m@" as metres) away from user text.

pint is imported lazily, on first use, so that importing this module costs nothing.

Unit cache. pint's start-up (its import and its registry, ~0.2-0.4 s) would be paid by
every command, since the catalog and the ontology's limits are written with units. The
answer for one unit text (its SI factor, or why it is refused) depends only on that text,
on this module's code and on pint's definition files, so it is kept on disk:
``$PARMOR_CACHE/units-KEY.json`` (default ``$XDG_CACHE_HOME/parmor``, else
``~/.cache/parmor``; ``PARMOR_CACHE=""`` turns the cache off). KEY is a hash of this
file and of pint's definition files and installed version: a change of either starts a new
file, so an entry is never stale. The file is written whole to a temporary file and renamed
over the old one (concurrent writers lose at most an entry, never corrupt the file); a
folder that cannot be written, or a file that cannot be read or does not validate, only
means pint is asked again. pint is imported only on a miss.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from adron.errors import InputError

if TYPE_CHECKING:
    import pint

__all__ = ["CACHE_ENV", "DIMENSIONS", "Dimension", "cache_folder", "quantity", "registry"]

#: Environment variable naming the folder of parmor's caches ("" turns them off).
CACHE_ENV = "PARMOR_CACHE"


class Dimension(NamedTuple):
    """A kind of quantity parmor reads.

    ``dimensionality`` is pint's dimensionality of the SI unit (as text); ``si_unit`` is
    the unit the returned floats are in (pint syntax, also shown in messages);
    ``example`` is shown in error messages; ``angle_power`` is the power of the radian
    the unit must carry (pint treats angles as dimensionless, so "10 Hz" would otherwise
    pass as an angular speed of 10 rad/s).
    """

    dimensionality: str
    si_unit: str
    example: str
    angle_power: int = 0


DIMENSIONS: dict[str, Dimension] = {
    "length": Dimension("[length]", "m", "30 cm"),
    "area": Dimension("[length] ** 2", "m**2", "300 cm^2"),
    "volume": Dimension("[length] ** 3", "m**3", "12 cm^3"),
    "volume_flow": Dimension("[length] ** 3 / [time]", "m**3/s", "12 mm^3/s"),
    "mass": Dimension("[mass]", "kg", "0.5 kg"),
    "force": Dimension("[mass] * [length] / [time] ** 2", "N", "5 N"),
    "torque": Dimension("[mass] * [length] ** 2 / [time] ** 2", "N*m", "1.8 kgf*cm"),
    "speed": Dimension("[length] / [time]", "m/s", "0.2 m/s"),
    "acceleration": Dimension("[length] / [time] ** 2", "m/s**2", "9.81 m/s^2"),
    "angle": Dimension("dimensionless", "rad", "10 deg", angle_power=1),
    "angular_speed": Dimension("1 / [time]", "rad/s", "60 rpm", angle_power=1),
    "angular_acceleration": Dimension("1 / [time] ** 2", "rad/s**2", "3 rad/s^2", 1),
    "time": Dimension("[time]", "s", "2 s"),
    "current": Dimension("[current]", "A", "1.5 A"),
    "voltage": Dimension("[mass] * [length] ** 2 / [time] ** 3 / [current]", "V", "11.1 V"),
    # SI: coulombs (1 Ah = 3600 C); battery capacities are usually written in mAh.
    "charge": Dimension("[current] * [time]", "C", "1500 mAh"),
    # Moduli and strengths.
    "pressure": Dimension("[mass] / [length] / [time] ** 2", "Pa", "3.5 GPa"),
    "density": Dimension("[mass] / [length] ** 3", "kg/m**3", "1240 kg/m^3"),
    "dimensionless": Dimension("dimensionless", "dimensionless", "0.02"),
}

_NUMBER = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*", re.S)
# One factor of a unit expression: a name, then an optional exponent.
_NAME = r"[A-Za-z_µμΩ°]+"
_EXPONENT = r"(?:\s*(?:\*\*|\^)\s*(?P<exp>[+-]?\d{1,2})|(?P<sup>⁻?[¹²³⁴⁵⁶⁷⁸⁹]+)|(?P<short>[23]))?"
_FACTOR = re.compile(rf"(?P<name>{_NAME}){_EXPONENT}")
# Between factors: an explicit operator (with optional spaces) or plain whitespace.
_OPERATOR = re.compile(r"\s*([*·⋅/])\s*|\s+")
_SUPERSCRIPTS = str.maketrans("⁻¹²³⁴⁵⁶⁷⁸⁹", "-123456789")


@functools.cache
def registry() -> pint.UnitRegistry:
    """The one pint registry of parmor (created on first use: pint is slow to import).

    pint's own definition cache (in the user's cache folder) cuts the registry's start-up
    from about 0.3 s to 0.02 s; where that folder cannot be written, it starts uncached. That
    cache is a pickle too: a folder another user owns or may write is not used
    (:func:`unsafe_cache_folder`, a one-line warning).
    """
    import pint
    import platformdirs  # pint's own dependency: where its ":auto:" cache folder is

    folder = platformdirs.user_cache_path(appname="pint", appauthor=False)
    why = unsafe_cache_folder(folder)
    if why is not None:
        _warn_unsafe(folder, why, "pint's definition cache")
        return pint.UnitRegistry()
    try:
        return pint.UnitRegistry(cache_folder=folder)
    except OSError:
        return pint.UnitRegistry()


def _label(dimension: str) -> str:
    """'angular_speed' -> 'an angular speed' (for messages)."""
    if dimension == "dimensionless":
        return "a plain number"
    words = dimension.replace("_", " ")
    return ("an " if words[0] in "aeiou" else "a ") + words


def _factors(unit_text: str) -> list[tuple[str, int]] | None:
    """``"kg/m^3"`` -> ``[("kg", 1), ("m", -3)]``; None when the text is not a unit."""
    factors: list[tuple[str, int]] = []
    pos, sign = 0, 1
    while True:
        match = _FACTOR.match(unit_text, pos)
        if match is None:
            return None
        if match["exp"] is not None:
            power = int(match["exp"])
        elif match["sup"] is not None:
            power = int(match["sup"].translate(_SUPERSCRIPTS))
        elif match["short"] is not None:
            power = int(match["short"])
        else:
            power = 1
        factors.append((match["name"], sign * power))
        pos = match.end()
        if pos == len(unit_text):
            return factors
        op = _OPERATOR.match(unit_text, pos)
        if op is None:
            return None
        sign = -1 if op.group(1) == "/" else 1
        pos = op.end()


class _Scale(NamedTuple):
    factor: float | None  # SI value of one unit; None when the dimension is wrong
    unknown: str | None  # a name pint does not know


def cache_folder() -> Path | None:
    """The folder of parmor's caches: ``$PARMOR_CACHE``, else ``$XDG_CACHE_HOME/parmor``,
    else ``~/.cache/parmor``; None when ``PARMOR_CACHE`` is set empty (no cache), or when
    the folder is not safe to use (:func:`unsafe_cache_folder`: a one-line warning)."""
    env = os.environ.get(CACHE_ENV)
    if env is not None:
        if not env.strip():
            return None
        folder = Path(env)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        folder = Path(base) / "parmor"
    why = unsafe_cache_folder(folder)
    if why is not None:
        _warn_unsafe(folder, why)
        return None
    return folder


def unsafe_cache_folder(folder: Path) -> str | None:
    """Why ``folder`` must not hold parmor's caches, or None when it may: it is absent
    (made private, 0700, when first written) or a folder of this user's that no one else
    may write. A cache is read back into the process (the knowledge base and the catalog
    are pickles, and unpickling runs code): a folder that another user owns or may write
    would let them plant a file that runs code in every parmor process."""
    import stat

    getuid = getattr(os, "getuid", None)
    if getuid is None:  # no POSIX owners (not a platform parmor runs on)
        return None
    try:
        st = os.stat(folder)
    except OSError:  # absent (made private when written), or unreachable (no cache then)
        return None
    if not stat.S_ISDIR(st.st_mode):
        return None  # every read and write there fails: no cache, and nothing to fear
    if st.st_uid != getuid():
        return f"it belongs to another user (uid {st.st_uid})"
    if st.st_mode & 0o022:
        who = (
            "its group and others"
            if st.st_mode & 0o002 and st.st_mode & 0o020
            else ("others" if st.st_mode & 0o002 else "its group")
        )
        return f"{who} may write it (mode {stat.S_IMODE(st.st_mode):04o}; chmod go-w fixes it)"
    return None


_WARNED: set[str] = set()


def _warn_unsafe(folder: Path, why: str, what: str = CACHE_ENV) -> None:
    """One line on stderr, once per folder and process: the cache is off and why."""
    import sys

    # gaits.base warns with the same words (gaits may not import adron): once in all
    if str(folder) in _WARNED | getattr(sys.modules.get("gaits.base"), "_WARNED", set()):
        return
    _WARNED.add(str(folder))
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(f"parmor: warning: not using the cache folder {folder} ({what}): {why}\n")


def read_cache_bytes(path: Path) -> bytes | None:
    """The bytes of the cache file ``path``, or None when it is absent, unreadable, not a
    regular file, a symbolic link, or not this user's own file that no one else may write
    (checked on the open file: a file put there by someone else is never read)."""
    import stat

    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        getuid = getattr(os, "getuid", None)
        foreign = getuid is not None and st.st_uid != getuid()
        if not stat.S_ISREG(st.st_mode) or foreign or st.st_mode & 0o022:
            return None
        with os.fdopen(fd, "rb") as f:
            fd = -1  # closed by the file object
            return f.read()
    except OSError:
        return None
    finally:
        if fd >= 0:
            os.close(fd)


def write_cache_file(path: Path, data: bytes) -> bool:
    """``data`` made the cache file ``path`` whole: a temporary file beside it renamed
    over it (concurrent writers write the same bytes; no reader sees half a file). False,
    and nothing left behind, where the folder cannot be written: a cache is only a
    shortcut. A folder it makes is private (0700): see :func:`unsafe_cache_folder`."""
    import contextlib
    import tempfile

    tmp = None
    try:
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}-", suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
        return True
    except OSError:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        return False


def read_cache_pickle(path: Path | None, tag: bytes, kind: type) -> object | None:
    """The object pickled in the cache file ``path`` after ``tag`` (written by
    :func:`write_cache_file`), when it is a ``kind``; None when absent, cut short, corrupt
    or foreign. A hit touches the file (recently used: kept by :func:`prune_cache`)."""
    import contextlib
    import pickle

    if path is None:
        return None
    try:
        data = read_cache_bytes(path)  # this user's own file, or nothing: see its doc
        if data is None or not data.startswith(tag):
            return None
        value = pickle.loads(data[len(tag) :])
    except Exception:  # noqa: BLE001 - a corrupt or foreign file is only a miss
        return None
    if not isinstance(value, kind):
        return None
    with contextlib.suppress(OSError):
        os.utime(path)
    return value


def prune_cache(folder: Path, patterns: tuple[str, ...], keep: int) -> None:
    """Remove all but the ``keep`` most recently used files of each glob pattern in
    ``folder``; errors are ignored (another process may prune at the same time)."""
    import contextlib

    for pattern in patterns:
        try:
            entries = sorted(folder.glob(pattern), key=lambda p: p.stat().st_mtime_ns)
        except OSError:
            continue
        for old in entries[: max(0, len(entries) - keep)]:
            with contextlib.suppress(OSError):
                old.unlink()


def _cache_key() -> str | None:
    """Hash of this module's code and pint's definitions and version; None without pint."""
    import hashlib
    from importlib.util import find_spec

    spec = find_spec("pint")
    if spec is None or spec.origin is None:
        return None
    pint_dir = Path(spec.origin).parent
    h = hashlib.sha256(Path(__file__).read_bytes())
    for name in ("default_en.txt", "constants_en.txt"):
        try:
            h.update((pint_dir / name).read_bytes())
        except OSError:
            h.update(b"-")
    stat = Path(spec.origin).stat()  # pint's own code: a new install has a new stat
    h.update(f"{spec.origin}|{stat.st_size}|{stat.st_mtime_ns}".encode())
    return h.hexdigest()[:20]


class _DiskCache:
    """Unit text -> _Scale, read from and written to one JSON file (see the module doc)."""

    def __init__(self) -> None:
        self.path: Path | None = None
        self.entries: dict[str, _Scale] | None = None  # None: not read yet

    def _file(self) -> Path | None:
        folder = cache_folder()
        if folder is None:
            return None
        key = _cache_key()
        return None if key is None else folder / f"units-{key}.json"

    @staticmethod
    def _read(path: Path) -> dict[str, _Scale]:
        """The valid entries of ``path``; {} when it is absent, unreadable or invalid."""
        raw = read_cache_bytes(path)
        try:
            data = json.loads(raw.decode("utf-8")) if raw is not None else {}
        except ValueError:
            return {}
        out: dict[str, _Scale] = {}
        if not isinstance(data, dict):
            return {}
        for k, v in data.items():
            ok = isinstance(v, list) and len(v) == 2
            factor, unknown = v if ok else (None, None)
            ok = ok and (
                factor is None
                or (
                    isinstance(factor, (int, float))
                    and not isinstance(factor, bool)
                    and math.isfinite(factor)
                    and factor > 0
                )
            )
            ok = ok and (unknown is None or isinstance(unknown, str))
            if not ok:
                return {}  # not a file this code wrote: ignore all of it
            out[k] = _Scale(None if factor is None else float(factor), unknown)
        return out

    def get(self, key: str) -> _Scale | None:
        if self.entries is None:
            self.path = self._file()
            self.entries = self._read(self.path) if self.path is not None else {}
        return self.entries.get(key)

    def put(self, key: str, value: _Scale) -> None:
        if self.entries is None:
            self.get(key)
        assert self.entries is not None
        self.entries[key] = value
        if self.path is None:
            return
        merged = {**self._read(self.path), **self.entries}  # keep what others wrote
        text = json.dumps({k: list(v) for k, v in sorted(merged.items())}, indent=0)
        import tempfile

        tmp = None
        try:
            self.path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.path.parent, prefix=".units-", suffix=".tmp")
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
            os.replace(tmp, self.path)
        except OSError:  # read-only or full: work on without writing
            self.path = None
            if tmp is not None:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)


_DISK = _DiskCache()


@functools.cache
def _scale(factors: tuple[tuple[str, int], ...], dimension: str) -> _Scale:
    """The SI value of one ``factors`` unit as ``dimension``: from the disk cache, else
    from pint (and then stored)."""
    key = dimension + "|" + " ".join(f"{name}^{power}" for name, power in factors)
    found = _DISK.get(key)
    if found is not None:
        return found
    found = _pint_scale(factors, dimension)
    _DISK.put(key, found)
    return found


def _pint_scale(factors: tuple[tuple[str, int], ...], dimension: str) -> _Scale:
    """The SI value of one ``factors`` unit as ``dimension``, asked of pint."""
    import pint

    ureg = registry()
    dim = DIMENSIONS[dimension]
    unit = ureg.dimensionless
    for name, power in factors:
        try:
            unit = unit * ureg.Unit(name) ** power
        except (pint.UndefinedUnitError, ValueError):
            return _Scale(None, name)
    try:
        one = ureg.Quantity(1.0, unit)
        base = dict(one.to_base_units().unit_items())
        if base.get("radian", 0) != dim.angle_power:
            return _Scale(None, None)
        return _Scale(float(one.to(dim.si_unit).magnitude), None)
    except pint.PintError:  # DimensionalityError, offset units (degC) and the like
        return _Scale(None, None)


def quantity(
    text: str | int | float,
    dimension: str,
    where: str,
    *,
    allow_zero: bool = False,
    allow_negative: bool = False,
) -> float:
    """The SI value of ``text``, a number with a unit of ``dimension`` (a DIMENSIONS key).

    ``where`` names the value in messages ("catalog.toml: actuator[2] (MG996R).mass").
    By default the value must be > 0; ``allow_zero`` accepts >= 0, ``allow_negative``
    any finite value. Angles come back in radians, charges in coulombs. Raises
    InputError for a bare number (unless dimensionless), an unknown unit, the wrong
    dimension, unreadable text, a non-finite value or a value of the wrong sign.
    """
    if dimension not in DIMENSIONS:
        raise ValueError(f"unknown dimension {dimension!r}; one of {sorted(DIMENSIONS)}")
    dim = DIMENSIONS[dimension]
    expected = f"expected {_label(dimension)} such as '{dim.example}'"
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise InputError(f"{where}: {expected}, got {_describe(text)}")
    if isinstance(text, str):
        match = _NUMBER.fullmatch(text)
        if not text.strip():
            raise InputError(f"{where}: empty value; {expected}")
        if match is None:
            raise InputError(f"{where}: cannot read '{text}'; {expected}")
        number, unit_text = float(match.group(1)), match.group(2)
    else:
        number, unit_text = float(text), ""
    if unit_text:
        factors = _factors(unit_text)
        if factors is None:
            raise InputError(f"{where}: cannot read the unit of '{text}'; {expected}")
        scale = _scale(tuple(factors), dimension)
        if scale.unknown is not None:
            raise InputError(f"{where}: unknown unit '{scale.unknown}' in '{text}'; {expected}")
        if scale.factor is None:
            raise InputError(f"{where}: {expected}, got '{text}'")
        value = number * scale.factor
    elif dimension == "dimensionless":
        value = number
    else:
        raise InputError(f"{where}: '{text}' has no unit; {expected}")
    if not math.isfinite(value):
        raise InputError(f"{where}: '{text}' is not finite; {expected}")
    if value < 0 and not allow_negative:
        raise InputError(f"{where}: must not be negative, got '{text}'")
    if value == 0 and not (allow_zero or allow_negative):
        raise InputError(f"{where}: must be positive, got '{text}'")
    return value


def _describe(value: Any) -> str:
    """A short description of a value of the wrong type, for messages."""
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return f"{type(value).__name__} {value!r}"
