"""From a study database or CSV to tidy frames, statistics, figures and the report."""
