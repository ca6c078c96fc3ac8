"""The contact dynamics engine (Moreau, Jean; Pérez Sec. 2, Eq. 11-12): rigid spheres
(3D) and disks (2D) with exact Signorini, Coulomb and Newton conditions, solved every
step by a nonlinear Gauss-Seidel over the contacts (docs/contact_dynamics.md)."""
