"""Observables: energies, packing, coordination, stresses; Bauer compression-law fits."""
