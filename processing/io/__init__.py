"""Files: signature.h5 and the HDF5 dataset store (shards, index, queries)."""
