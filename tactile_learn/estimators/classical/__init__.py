"""Classical estimators: numpy/scipy only (no torch, no onnxruntime)."""
