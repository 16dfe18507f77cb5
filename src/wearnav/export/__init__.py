"""Exporting trained models to ONNX and TorchScript and running them (issue 18 §4): see
:mod:`wearnav.export.header` for what an exported file carries, :mod:`wearnav.export.write` for
``wearnav export``, :mod:`wearnav.export.runtime` for running one in ``wearnav track`` /
``wearnav classify``."""
