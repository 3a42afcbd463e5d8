"""`wtftc scorecard`: a controller against its baseline over one case matrix, with its
statistics (docs/scorecard.md)."""
