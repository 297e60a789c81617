"""Reports: the identification report (:mod:`kukaid.report.fit_report`), a multi-page PDF."""
from kukaid.report.data import ReportData, ReportError, load_report_data
from kukaid.report.fit_report import build_report, make_report
from kukaid.report.layout import write_report

__all__ = ["ReportData", "ReportError", "build_report", "load_report_data", "make_report", "write_report"]
