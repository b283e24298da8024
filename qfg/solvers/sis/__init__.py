"""Algorithm 1 of Mor and Indelman: sequential importance sampling over camera trajectories
(``method="full"`` and ``method="fast"``).
"""
