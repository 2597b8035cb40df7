#!/bin/sh
# X11/GL client libraries that `import bpy` needs on a headless Debian/Ubuntu machine, and headless Chromium for the
# report tests.
# Installs them only where they are missing and apt-get is usable; otherwise says what to install.
set -e
LIBS="libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libsm6 libice6 libgl1 libxext6 libxcb1"
missing=""
for lib in libX11.so.6 libXrender.so.1 libXfixes.so.3 libXi.so.6 libxkbcommon.so.0 libSM.so.6 libICE.so.6 libGL.so.1 libXext.so.6 libxcb.so.1; do
    ldconfig -p 2>/dev/null | grep -q "$lib" || missing="$missing $lib"
done
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
if [ -n "$missing" ]; then
    if command -v apt-get >/dev/null 2>&1; then
        echo "installing X11/GL libraries for bpy (missing:$missing)"
        $SUDO apt-get update -qq && $SUDO apt-get install -y -qq $LIBS >/dev/null
    else
        echo "warning: missing$missing; install your system's equivalents of: $LIBS (needed by the Blender backend only)" >&2
    fi
fi
# Headless Chromium opens the pages of `platesynth report` in tests/test_report.py (skipped without it).
if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1; then
    if command -v apt-get >/dev/null 2>&1; then
        echo "installing chromium for the report tests"
        { $SUDO apt-get update -qq && $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; } ||
            echo "warning: could not install chromium; tests/test_report.py will skip opening the pages" >&2
    else
        echo "warning: chromium not found; tests/test_report.py will skip opening the pages" >&2
    fi
fi
