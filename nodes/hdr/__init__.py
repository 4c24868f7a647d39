"""HDR point cloud nodes (paper 001): ``hdr_expander``, ``cloud_file`` and ``hdr_cloud_writer``."""
