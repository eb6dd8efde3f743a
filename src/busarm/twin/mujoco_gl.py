"""MuJoCo with a headless OpenGL backend for the twin's cameras: the import, and the
renderers, one per thread (a GL context lives in the thread that made it)."""

from __future__ import annotations

import copy
import ctypes.util
import os
import threading
from typing import Any

from busarm.errors import TwinError

__all__ = [
    "GL_PACKAGES",
    "LIVE_SLICES",
    "LIVE_STACKS",
    "Renderers",
    "import_mujoco",
]


LIVE_SLICES = 16
LIVE_STACKS = 8
"""Facets round a live view's spheres, capsules and cylinders, and along them."""
GL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri (or libosmesa6 for MUJOCO_GL=osmesa)"


def _choose_gl_backend() -> str:
    """MUJOCO_GL as given, else EGL or OSMesa, whichever this machine has."""
    given = os.environ.get("MUJOCO_GL")
    if given:
        if given not in ("egl", "osmesa", "glfw"):
            raise TwinError(f"MUJOCO_GL={given!r}; allowed: egl, osmesa (headless) or glfw")
        return given
    if ctypes.util.find_library("EGL"):
        return "egl"
    if ctypes.util.find_library("OSMesa"):
        return "osmesa"
    raise TwinError(f"no headless OpenGL for the twin's camera: install {GL_PACKAGES} "
                    "(Debian/Ubuntu: sudo apt-get install ...), or set MUJOCO_GL")


def import_mujoco() -> Any:
    """The ``mujoco`` module, its OpenGL backend chosen first (``MUJOCO_GL``); TwinError
    saying what to install when it cannot start."""
    os.environ["MUJOCO_GL"] = _choose_gl_backend()
    if os.environ["MUJOCO_GL"] == "egl":
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    try:
        import mujoco
    except ImportError as exc:
        raise TwinError(f"the twin needs MuJoCo: pip install mujoco ({exc})") from exc
    except Exception as exc:  # MuJoCo's GL loaders raise whatever their library does
        raise TwinError(f"MuJoCo cannot start its {os.environ['MUJOCO_GL']!r} OpenGL backend "
                        f"({type(exc).__name__}: {exc}); install {GL_PACKAGES}, or set "
                        "MUJOCO_GL=egl or osmesa") from exc
    return mujoco


class Renderers:
    """The renderers of one simulation, made on demand per thread, size and kind."""

    def __init__(self, mujoco: Any) -> None:
        self._mujoco = mujoco
        self._local = threading.local()
        self._all: list[Any] = []

    def get(self, model: Any, width: int, height: int, live: bool = False) -> Any:
        """This thread's renderer of ``model`` at ``width`` x ``height`` (``live``: one
        drawn without multisampling)."""
        cache = getattr(self._local, "renderers", None)
        if cache is None:
            cache = self._local.renderers = {}
        key = (width, height, live)
        if key not in cache:
            if live:  # the same model drawn without multisampling: a live view's own context
                model = copy.copy(model)
                model.vis.quality.offsamples = 0
                # Round shapes with fewer facets (MuJoCo's default 28 x 16): their
                # vertices are a quarter of a live frame's cost on a CPU, and a person
                # sees no difference (under 0.03 of a grey level on average).
                model.vis.quality.numslices = LIVE_SLICES
                model.vis.quality.numstacks = LIVE_STACKS
            try:
                cache[key] = self._mujoco.Renderer(model, height, width)
            except Exception as exc:  # the GL backend's own errors vary by backend
                raise TwinError(
                    f"cannot render with MUJOCO_GL={os.environ.get('MUJOCO_GL')}: {exc}; "
                    f"install {GL_PACKAGES}") from exc
            self._all.append(cache[key])
        return cache[key]

    def release(self) -> None:
        """Close the renderers this thread made."""
        cache = getattr(self._local, "renderers", None) or {}
        for renderer in cache.values():
            renderer.close()
            self._all.remove(renderer)
        self._local.renderers = {}

    def forget_others(self) -> None:
        """Drop the renderers of threads that did not release theirs: their GL context
        cannot be made current here, so they are left to the process's exit."""
        self._all.clear()
