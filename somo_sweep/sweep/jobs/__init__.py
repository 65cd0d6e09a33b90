"""Jobs: one trial with everything it needs, the job table, the code a trial runs."""
