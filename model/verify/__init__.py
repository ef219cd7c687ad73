"""The checker of hand-derived formulas: UFL reference values of psi, P and A (emit), comparisons
with a user's own values (check), and the formulas printed in the seed documents (seeds)."""

from model.verify.reference import (
    QUANTITIES,
    CheckRow,
    ReferenceEvaluator,
    check,
    compare,
    deformation_samples,
    emit,
    field_samples,
    format_rows,
    load_for_check,
    reference,
)

__all__ = ["QUANTITIES", "CheckRow", "ReferenceEvaluator", "check", "compare", "deformation_samples", "emit",
           "field_samples", "format_rows", "load_for_check", "reference"]
