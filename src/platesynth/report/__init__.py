"""``platesynth report``: one self-contained, offline HTML page for a study, a dataset or an optimisation run."""

from platesynth.report.html import REPORT_NAME, build_report, report_kind, write_report

__all__ = ["REPORT_NAME", "build_report", "report_kind", "write_report"]
