"""Observables: energies, packing, coordination, stresses."""
