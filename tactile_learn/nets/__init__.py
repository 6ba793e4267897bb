"""Torch networks, one module per task. Imported only by training and export."""
