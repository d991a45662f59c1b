"""Files: HDF5 results and checkpoints, the mesh group, ParaView VTU/PVD, pictures and videos."""
