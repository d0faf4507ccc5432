//! Geometric multigrid on the voxel grid (LOBPCG's preconditioner). Not yet written.
