"""Node implementations. ``BUILTIN`` maps each registered node type name to ``module:Class``.

Swapping an implementation in a graph means changing one ``node:`` line to another name here
(or to any ``module:Class``, or to a name another package registers in the ``probeless.nodes``
entry-point group).
"""

BUILTIN: dict[str, str] = {
    "pattern_source": "probeless.nodes.demo.pattern:PatternSource",
    "image_transform": "probeless.nodes.demo.transform:ImageTransform",
    "summary_sink": "probeless.nodes.demo.summary:SummarySink",
    "bag_recorder": "probeless.nodes.bag.recorder:BagRecorder",
    "bag_player": "probeless.nodes.bag.player:BagPlayer",
    "rosbag_player": "probeless.nodes.bag.rosbag_player:RosbagPlayer",
    "rgbd_dataset": "probeless.nodes.sensors.rgbd_dataset:RgbdDatasetPlayer",
    "fisheye_player": "probeless.nodes.sensors.fisheye_player:FisheyePlayer",
    "opencv_camera": "probeless.nodes.sensors.opencv_camera:OpenCvCamera",
    "realsense": "probeless.nodes.sensors.realsense:RealSenseCamera",
    "dense_slam": "probeless.nodes.tracking.slam:DenseSlamNode",
    "pose_interp": "probeless.nodes.tracking.pose_interp:PoseInterp",
    "coarse_texturer": "probeless.nodes.coarse.texturer:CoarseTexturer",
    "brightness_estimator": "probeless.nodes.coarse.brightness:BrightnessEstimator",
    "cubemap_renderer": "probeless.nodes.envmap.cubemap:CubemapRenderer",
    "baseline_envmap": "probeless.nodes.envmap.baseline:BaselineEnvmap",
    "video_writer": "probeless.nodes.output.writers:VideoWriter",
    "png_writer": "probeless.nodes.output.writers:PngWriter",
    "ibl_compositor": "probeless.nodes.ibl.compositor:IblCompositor",
    "video360_source": "probeless.nodes.pano.sources:Video360Source",
    "panorama_source": "probeless.nodes.pano.sources:PanoramaSource",
    "itmo": "probeless.nodes.pano.lighting:InverseToneMap",
    "diffuse_map": "probeless.nodes.pano.lighting:DiffuseMap",
    "pano_compositor": "probeless.nodes.pano.compositor:PanoCompositor",
    "fisheye_undistort": "probeless.nodes.sensors.undistort:FisheyeUndistort",
    "synthetic_rig": "probeless.nodes.sensors.synthetic_rig:SyntheticRig",
    "hdr_expander": "probeless.nodes.hdr.expander:HdrExpander",
    "hdr_atlas_expander": "probeless.nodes.hdr.atlas_expander:HdrAtlasExpander",
    "cloud_file": "probeless.nodes.hdr.cloud_file:CloudFile",
    "hdr_cloud_writer": "probeless.nodes.hdr.writer:HdrCloudWriter",
    "pbgi_renderer": "probeless.nodes.pbgi.renderer:PbgiRendererNode",
    "cloud_views": "probeless.nodes.pbgi.views:CloudViews",
    "rerun_sink": "probeless.nodes.viz.rerun_sink:RerunSink",
    "foxglove_bridge": "probeless.nodes.viz.foxglove_bridge:FoxgloveBridge",
    "bench_source": "probeless.nodes.bench.bus:BenchSource",
    "bench_sink": "probeless.nodes.bench.bus:BenchSink",
    "bench_camera_source": "probeless.nodes.bench.bag:CameraSource",
    "bench_timing_source": "probeless.nodes.bench.bag:TimingSource",
    "bench_timing_sink": "probeless.nodes.bench.bag:TimingSink",
    "bench_jitter_worker": "probeless.nodes.bench.bag:JitterWorker",
}
