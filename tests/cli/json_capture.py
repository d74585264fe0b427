"""Run a command with ``--json`` and keep what the facade function it calls returned."""

from __future__ import annotations

import contextlib
import io
import json

import cli
import pefsim


def printed(obj) -> object:
    """Return ``obj`` as the program prints JSON (numpy values plain, inf refused), read back."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        cli.print_json(obj)
    return json.loads(buf.getvalue())


def run_json(capsys, monkeypatch, name: str, argv: list[str]) -> tuple[object, object]:
    """Run ``pefsim ARGV --json``; return the printed document and what ``pefsim.<name>`` returned."""
    returned = []
    real = getattr(pefsim, name)

    def recording(*args, **kwargs):
        returned.append(real(*args, **kwargs))
        return returned[-1]

    monkeypatch.setattr(pefsim, name, recording)
    code = cli.main([*argv, "--json"])
    out = capsys.readouterr().out
    assert code in (0, 1) and len(returned) == 1, (code, returned)
    return json.loads(out), returned[0]
