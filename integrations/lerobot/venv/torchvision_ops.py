"""Let PyPI's torchvision import beside a CPU-only build of torch.

PyPI's torchvision wheel carries C++ ops (``torchvision/_C.so``) linked against CUDA's
libraries; beside the CPU build of torch they do not load, and torchvision then fails at
import because it registers fake kernels for two ops (``nms``, ``qnms``) that only ``_C``
would have defined. This module defines those two schemas, just before torchvision is
first imported (a ``.pth`` file installs the hook), so that torchvision imports; its
pure-PyTorch parts (transforms, the ResNet backbones LeRobot's policies use) then work,
and its C++ ops raise torchvision's own "Couldn't load custom C++ ops" error if called.
"""

from __future__ import annotations

import importlib.abc
import sys
from typing import Any

_SCHEMAS = (
    "nms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor",
    "qnms(Tensor dets, Tensor scores, float iou_threshold) -> Tensor",
)
_library: Any = None


def _define() -> None:
    global _library
    import torch

    if _library is not None or hasattr(torch.ops.torchvision, "nms"):
        return
    _library = torch.library.Library("torchvision", "FRAGMENT")
    for schema in _SCHEMAS:
        _library.define(schema)


class _Hook(importlib.abc.MetaPathFinder):
    def find_spec(self, name: str, path: Any = None, target: Any = None) -> None:
        if name == "torchvision":
            sys.meta_path.remove(self)
            _define()
        return None


def install() -> None:
    """Define the schemas the moment torchvision is first imported."""
    if "torchvision" in sys.modules:
        return
    sys.meta_path.insert(0, _Hook())
