"""The report's statistics, below everything else it holds: bootstrap intervals, their resamples, grouped sums."""
