"""The Coulomb consistency benchmark's parts (``benchmarks/coulomb_consistency.py`` runs them):
the test grasps and their critical friction coefficients from the project's quality code
(``grasps``), and the same grasps simulated in pybullet and in MuJoCo (``scenes``)."""
