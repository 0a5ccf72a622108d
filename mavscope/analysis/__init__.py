"""Analysis over dissected frames: display filters, statistics, forensic reconstruction, findings."""
