"""Simulated users (scripted and learned), the benchmark and the ``vrloco`` command line."""
