"""OpenCV VideoCapture backend: USB (V4L2, DirectShow, ...) and GStreamer cameras."""

from drivers.opencv.camera import OpenCVCamera

__all__ = ["OpenCVCamera"]
