"""Inpainting methods for dynamic point clouds, on plain numpy arrays.

A frame is an (N, 3) float array; a sequence is a list of them. Use `get_method(name, **params)`;
heavy dependencies load only when a method is built.
"""

from dpcbench.methods.base import InpaintingMethod, PerFrameMethod
from dpcbench.methods.registry import available_methods, get_method, method_class

__all__ = ["InpaintingMethod", "PerFrameMethod", "available_methods", "get_method", "method_class"]
