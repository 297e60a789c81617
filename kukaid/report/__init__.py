"""Reports: the identification report (:mod:`kukaid.report.fit_report`), a multi-page PDF."""
from kukaid.report.fit_report import (ReportData, ReportError, build_report, load_report_data, make_report,
                                      write_report)

__all__ = ["ReportData", "ReportError", "build_report", "load_report_data", "make_report", "write_report"]
