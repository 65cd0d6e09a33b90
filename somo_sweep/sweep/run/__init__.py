"""Running a study: workers, rounds, sampling, replicas, numerics, finished rows."""
