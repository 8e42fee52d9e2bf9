"""The body: skeleton (rig, pose sequences), the skinned CC0 avatar, linear-blend skinning, the seed's
point scatterers and skin markers, and the mesh geometry helpers they share."""
