"""A saved rerun recording read back with rerun's own reader, for the tests of what was logged."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from rerun.chunk import RrdReader

from interop.recording import entities as E


class Readback:
    """All chunks of a recording's data store, grouped by entity path (without leading '/')."""

    def __init__(self, path) -> None:
        self.reader = RrdReader(path)
        self.chunks = defaultdict(list)
        for chunk in self.reader.store().stream().to_chunks():
            self.chunks[chunk.entity_path.lstrip("/")].append(chunk)

    def column(self, entity: str, component: str, timeline: str | None = E.TIMELINE):
        """Rows of ``component`` over all chunks of ``entity``, sorted by time; (times_ns, rows)."""
        times, rows = [], []
        for chunk in self.chunks[entity]:
            batch = chunk.to_record_batch()
            if component not in batch.schema.names:
                continue
            values = batch.column(component).to_pylist()
            if timeline is not None and timeline in batch.schema.names:
                ts = batch.column(timeline).cast("int64").to_numpy()
            else:
                ts = np.zeros(len(values), dtype=np.int64)
            times.extend(ts)
            rows.extend(values)
        order = np.argsort(np.asarray(times), kind="stable")
        return np.asarray(times)[order], [rows[i] for i in order]
