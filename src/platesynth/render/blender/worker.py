"""Blender side: the worker process, ``python -m platesynth.render.blender.worker``.

It imports ``bpy`` once, then reads one JSON request per line on stdin and answers one JSON line on stdout:

- ``{"op": "ping"}`` -> ``{"ok": true, "blender": "5.0.1", "pid": ..., "home": ...}``
- ``{"op": "render", "scene": <description>, "options": {...}, "out_dir": DIR}`` -> ``{"ok": true, "files": {...}}``
  (see :func:`platesynth.render.blender.inside.render.render_to_files`)
- ``{"op": "export", "scene": <description>, "options": {...}, "path": FILE}`` -> ``{"ok": true, "path": FILE}``
- ``{"op": "quit"}`` -> the process exits.

An exception inside Blender becomes ``{"ok": false, "error": "Type: message", "traceback": ...}``; the worker
stays usable. Everything Blender itself prints goes to stderr (the host's log file), never to the reply pipe.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import time
import traceback
from typing import Any, TextIO


def _take_over_stdout() -> TextIO:
    """Keep the real stdout for replies and point file descriptor 1 at stderr, where Blender's chatter belongs."""
    replies = os.fdopen(os.dup(1), "w", buffering=1, encoding="utf-8")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    return replies


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def handle(request: dict[str, Any]) -> dict[str, Any]:
    """Serve one request (inside Blender) and return the reply's payload."""
    from platesynth.render.blender.inside import render as inside_render

    op = request.get("op")
    if op == "ping":
        import bpy

        return {"blender": bpy.app.version_string, "pid": os.getpid(), "home": os.environ.get("HOME", "")}
    if op == "render":
        files = inside_render.render_to_files(request["scene"], request.get("options", {}), request["out_dir"])
        return {"files": files}
    if op == "export":
        path = inside_render.export_blend(request["scene"], request.get("options", {}), request["path"])
        return {"path": path}
    raise ValueError(f"unknown request op {op!r}")


def main() -> None:
    """Serve requests until stdin closes or a ``quit`` request arrives."""
    replies = _take_over_stdout()

    def send(message: dict[str, Any]) -> None:
        replies.write(json.dumps(message) + "\n")
        replies.flush()

    import bpy  # the expensive import, once per worker

    send({"event": "ready", "pid": os.getpid(), "blender": bpy.app.version_string})
    for line in sys.stdin:
        if not line.strip():
            continue
        started, cpu_started = time.perf_counter(), _cpu_seconds()
        try:
            request = json.loads(line)
            if request.get("op") == "quit":
                break
            payload = handle(request)
            reply = {"ok": True, **payload}
        except Exception as exc:  # every error inside Blender goes back to the host, which raises it for the user
            text = traceback.format_exc()
            sys.stderr.write(text)
            sys.stderr.flush()
            reply = {"ok": False, "error": f"{type(exc).__name__}: {exc}", "traceback": text}
        reply["seconds"] = time.perf_counter() - started
        reply["cpu_seconds"] = _cpu_seconds() - cpu_started  # all threads: what other load on the machine hardly changes
        reply["peak_rss_mb"] = _peak_rss_mb()
        send(reply)


if __name__ == "__main__":
    main()
