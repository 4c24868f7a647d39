"""Shared geometry maths (bottom layer: numpy only, imports nothing of probeless but ``errors``).

* :mod:`~probeless.geom.rotation`: quaternions ``[x, y, z, w]``, slerp, roll-pitch-yaw, rigid 4x4 transforms;
* :mod:`~probeless.geom.projection`: OpenCV pinhole -> GL clip-space and view matrices;
* :mod:`~probeless.geom.cube`: cubemap texel directions, solid angles, nearest lookup, face matrices;
* :mod:`~probeless.geom.polygon`: 2-D polygon predicates (area, simplicity, containment);
* :mod:`~probeless.geom.floorplan`: the one floorplan validator.
"""
