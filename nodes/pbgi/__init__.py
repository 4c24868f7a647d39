"""Point-based GI nodes (paper 001, §5): ``pbgi_renderer`` (objects relit by the room's point cloud, composited into
the RGB frame) and ``cloud_views`` (a virtual camera splatting a cloud along an arc: frames of a scan)."""
