"""Loading: input tables, lab tables (feed, fine and coarse products) and Tromp points."""
