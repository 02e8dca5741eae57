"""Table I evaluation: run policies on shared test episodes, compute every column, report."""

from .metrics import recovery_rate, table1_columns
from .paper import PAPER_TABLE1
from .report import markdown_table, plot_difference_histogram, plot_paths, write_report
from .runner import EvalResult, evaluate
from .suite import BASE_CASE_ROWS, paper_rows_for, print_table, run_eval

__all__ = [
    "BASE_CASE_ROWS", "EvalResult", "PAPER_TABLE1", "evaluate", "markdown_table", "paper_rows_for",
    "plot_difference_histogram", "plot_paths", "print_table", "recovery_rate", "run_eval",
    "table1_columns", "write_report",
]
