"""Analysis of recorded runs: report, plots, CSV export."""
