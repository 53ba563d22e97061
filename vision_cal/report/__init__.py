"""Reports: summaries on stdout, report.json and the HTML report rendered from it."""
