"""Linear analyses of the flat web: equilibrium and stiffness assembly, prestressability by spin."""
