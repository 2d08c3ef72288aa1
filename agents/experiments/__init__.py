"""Experiments and figures reproducing the source papers."""
