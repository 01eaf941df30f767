"""flightrecon.report: plots of a reconstruction and a self-contained HTML page."""

from flightrecon.report.html import write_report
from flightrecon.report.plots import make_figures

__all__ = ["make_figures", "write_report"]
