"""Outputs: figures, reports, export, result views and the all-or-nothing writing of output folders."""
