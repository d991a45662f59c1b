"""The paper's analytical deployment model (Eqs. 4-8), its solution and its comparison with FE runs."""
