"""How a sweep's Parquet parts are encoded on disk, read back (by column), and checked.

Size (`docs/design.md` §5: steps are the bulk of a sweep). Per-step parts are stored lean:

- every float of :data:`~sim.montecarlo.rows.STEP_SCHEMA` as float32, which keeps a
  relative resolution of 2**-24 (6e-8): a position at 16 .. 32 m to 1.9 um (3.8 um at
  32 .. 64 m), an angle to 2.4e-7 rad, a time of 64 .. 128 s to 7.6 us (the control step is
  16.7 ms), a variance of 1e-6 m^2 to 6e-14 m^2, and errors, bounds and the NEES to 6e-8 of
  their value; what is given up is bit-exactness against the episode's float64 arrays. But a
  position's resolution is relative to the site's coordinates, not to the error: a world drawn
  in site coordinates (a CAD drawing or a map 700 km from its origin, as random worlds are
  drawn) kept its positions only to 6-8 cm, where the estimate is millimetres from the truth. A
  part whose positions float32 would round by more than :data:`POSITION_RESOLUTION` keeps them
  float64 (:func:`positions_kept`; 30 % more bytes for such a part);
- floats with BYTE_STREAM_SPLIT (the high bytes of slowly varying values compress well
  once apart), step and fix indices with DELTA_BINARY_PACKED (an arange costs ~0), the
  constant run column and small integer or boolean columns with dictionary/RLE, and zstd
  level 9 over all (about 50 ms per warehouse part, against tens of seconds per episode);
- a CRC32 per page, verified on every read: zstd frames carry no checksum, so without it a
  byte garbled in the middle of a part decodes silently to other numbers (tested).

Fix and run parts keep float64: the containment, promise and bound checks compare values
at their tolerance edges, and fixes are ~8 % of the steps' rows. On the warehouse, one run's
steps part goes from 391 KB to ~118 KB, its fixes part from 36 KB to 29 KB (see
``benchmarks/montecarlo.py``).

Readers return the logical schema (float64), whatever the part's storage type, so parts
written before this format (float64 throughout) and after it read alike, also mixed in one
directory that an older sweep was resumed into. A part that does not read back raises
:class:`DamagedPartError` naming the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from scenarios.errors import OutputError

COMPRESSION = "zstd"
COMPRESSION_LEVEL = 9
DELTA_COLUMNS = frozenset({"step", "fix"})
"""Monotone indices: delta encoding stores an arange in a few bytes."""


class DamagedPartError(OutputError):
    """A part file of a sweep directory does not read back (truncated, empty, garbage, wrong schema)."""

    def __init__(self, path: Path, reason: str) -> None:
        self.path = Path(path)
        self.reason = reason
        super().__init__(f"{path}: does not read back ({reason})")


LATER_COLUMNS = frozenset({"lost_guarantee", "excused", "unplanned", "collisions", "contact_t", "contact_x",
                           "contact_y", "contact_s", "contact_with", "stuck", "stall_time", "stuck_bound", "stall_t",
                           "stall_x", "stall_y", "stall_s", "deadlocked", "longest_wait", "wait_bound", "wait_t",
                           "wait_x", "wait_y", "waited_for", "predicted_wait",
                           "predicted_wait_time"})
"""Columns added after sweeps were first written: a part without one reads back with it null
(the runs' ``lost_guarantee``: not tested; the steps' ``excused``: nothing excused; the fixes'
``unplanned``: not recorded; what a run did, :mod:`sim.episode.outcome`: not watched)."""


def lean(schema: pa.Schema) -> pa.Schema:
    """Return ``schema`` with float64 fields as float32 (the storage of per-step parts)."""
    return pa.schema([pa.field(f.name, pa.float32()) if pa.types.is_float64(f.type) else f for f in schema])


POSITIONS = ("true_x", "true_y", "est_x", "est_y")
"""Step columns in world coordinates [m]."""
POSITION_RESOLUTION = 1e-5
"""Largest rounding of a stored position [m]: a hundredth of the millimetre an estimate is off."""


def positions_kept(storage: pa.Schema, columns: dict) -> pa.Schema:
    """Return ``storage`` with :data:`POSITIONS` as float64 if float32 would round them too much.

    Too much: by more than :data:`POSITION_RESOLUTION`, i.e. coordinates beyond
    ``2**24 POSITION_RESOLUTION`` = 168 m.

    Parameters
    ----------
    storage : pyarrow.Schema
        A steps part's lean storage (:func:`lean`).
    columns : dict of str to numpy.ndarray
        The part's columns (the :data:`POSITIONS` among them, [m]).
    """
    limit = POSITION_RESOLUTION * 2.0**24      # float32 rounds |x| by at most |x| 2**-24
    # all four or none: est - true is read from them
    far = any(float(np.max(np.abs(c), initial=0.0, where=np.isfinite(c))) > limit
              for c in (np.asarray(columns[n], dtype=float) for n in POSITIONS if n in columns))
    return pa.schema([pa.field(f.name, pa.float64()) if far and f.name in POSITIONS else f for f in storage])


def write_parquet(table: pa.Table, path: Path) -> None:
    """Write ``table`` to ``path`` with the encodings of the module docstring (raises OSError)."""
    floats, delta, dictionary = [], {}, []
    for f in table.schema:
        leaf = f.type.value_type if pa.types.is_list(f.type) else f.type
        if pa.types.is_floating(leaf):
            floats.append(f.name)
        elif f.name in DELTA_COLUMNS and pa.types.is_integer(f.type):
            delta[f.name] = "DELTA_BINARY_PACKED"
        else:
            dictionary.append(f.name)
    pq.write_table(table, path, compression=COMPRESSION, compression_level=COMPRESSION_LEVEL,
                   use_dictionary=dictionary, use_byte_stream_split=floats or False,
                   column_encoding=delta or None, write_page_checksum=True)


def _reason(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:160]


def read_part(path: Path, schema: pa.Schema, columns: list[str] | None = None) -> pa.Table:
    """Read one part as ``schema`` (projected to ``columns``); raises DamagedPartError if it does not read back."""
    names = columns if columns is not None else schema.names
    try:
        if path.stat().st_size == 0:
            raise DamagedPartError(path, "empty file")
        # ParquetFile.read, not pq.read_table: the latter builds a dataset per file, ~3x slower here.
        with pq.ParquetFile(path, page_checksum_verification=True) as part:
            have = set(part.schema_arrow.names)
            # a part written before a column was added reads back with that column null
            absent = [n for n in names if n not in have and n in LATER_COLUMNS]
            table = part.read(columns=[n for n in names if n not in absent])
            for n in absent:
                table = table.append_column(schema.field(n), pa.nulls(table.num_rows, schema.field(n).type))
    except DamagedPartError:
        raise
    except FileNotFoundError:
        raise DamagedPartError(path, "missing") from None
    except (OSError, pa.ArrowException, ValueError) as exc:
        raise DamagedPartError(path, _reason(exc)) from None
    target = pa.schema([schema.field(n) for n in names])
    try:
        table = table.select(names)
        return table if table.schema.equals(target) else table.cast(target)
    except (pa.ArrowException, ValueError, KeyError) as exc:
        raise DamagedPartError(path, f"not a part of this schema: {_reason(exc)}") from None


def read_parts(paths: list[Path], schema: pa.Schema, columns: list[str] | None = None) -> pa.Table:
    """Read parts (in the order given) into one table of ``schema`` projected to ``columns``."""
    names = columns if columns is not None else schema.names
    missing = [n for n in names if n not in schema.names]
    if missing:
        raise KeyError(f"no column {missing[0]!r} in this table (columns: {', '.join(schema.names)})")
    if not paths:
        return pa.schema([schema.field(n) for n in names]).empty_table()
    return pa.concat_tables([read_part(p, schema, names) for p in paths])


def check_part(path: Path, schema: pa.Schema, run: int, rows: int | None = None) -> None:
    """Read a whole part back and check it is run ``run``'s (with ``rows`` rows if given).

    Decompressing every page (not just the footer) also finds a part garbled in the middle.
    Raises DamagedPartError otherwise.
    """
    table = read_part(path, schema)
    if rows is not None and table.num_rows != rows:
        raise DamagedPartError(path, f"{table.num_rows} rows, expected {rows}")
    runs = table.column("run")
    if table.num_rows and (runs.null_count or pc.min_max(runs).as_py() != {"min": run, "max": run}):
        raise DamagedPartError(path, f"holds rows of another run than {run}")
