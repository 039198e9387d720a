"""ancsh.data: objects and depth frames.

- :mod:`ancsh.data.procedural` - the paper's five categories, seeded, with a train/test split
- :mod:`ancsh.data.urdf` - PartNet-Mobility / ReplicaCAD URDF -> ArticulatedModel
- :mod:`ancsh.data.paths` - where the shared real-object data lives

Submodules are imported on use (they pull in trimesh/open3d/h5py).
"""
