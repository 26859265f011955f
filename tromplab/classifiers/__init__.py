"""Sieve classifiers: velocity-probability identification, random walk, Markov layer, pulp screens, choice."""
