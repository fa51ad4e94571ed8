"""bfemp: coupled MPM-FEM simulation of elastic bodies in contact."""
