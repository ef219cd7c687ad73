"""Data on a domain that the forms read: fibre directions, activation, shape targets, polar rotations.

Each is a dolfinx Function (DG0 per cell, or per quadrature point), so changing its values between
steps never recompiles a form.
"""
