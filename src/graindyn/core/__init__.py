"""State, materials, neighbour search, walls, integrators and the compiled time loop."""
