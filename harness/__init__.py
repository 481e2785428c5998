"""The visual regression harness: feature matrix, scoring, references, report.

It reads rendered images through ``wrt``; nothing under ``wrt/`` or ``kernels/`` imports it.
"""
