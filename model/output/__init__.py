"""Results on disk: summary.json, XDMF and VTU time series (writer) and the PNG (render).

This package's __init__ imports nothing: ``python -m model.output.render`` must run in a process that
never loads dolfinx (see render.py).
"""
