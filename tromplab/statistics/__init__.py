"""Statistics on fitted curves: intervals and model averages, comparisons between experiments, trends over time, hydrocyclone water recovery."""
