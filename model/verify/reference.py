"""The ``verify`` tool's names under their former module (model.verify.reference): the code lives in
evaluator (ReferenceEvaluator, reference), samples, emitter, checker and report."""

from model.verify.checker import check, check_file, compare, load_for_check
from model.verify.emitter import emit
from model.verify.evaluator import QUANTITIES, ReferenceEvaluator, reference
from model.verify.report import CheckRow, Report, format_rows
from model.verify.samples import deformation_samples, field_samples

__all__ = ["QUANTITIES", "CheckRow", "Report", "ReferenceEvaluator", "check", "check_file", "compare",
           "deformation_samples", "emit", "field_samples", "format_rows", "load_for_check", "reference"]
