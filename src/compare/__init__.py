"""Comparison side of pgi: metrics, tables, convergence fits and the HTML report."""
