"""HDR point cloud nodes (paper 001): ``hdr_expander``, ``hdr_atlas_expander`` (the coarse model's atlas),
``cloud_file`` and ``hdr_cloud_writer``."""
