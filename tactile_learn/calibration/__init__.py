"""Calibration of real sensors: fitting a device's own response, and the front ends that apply it."""
