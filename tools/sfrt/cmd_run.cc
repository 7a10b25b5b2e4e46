// sfrt run: the real-time pipeline (pipeline/) from a camera pair or recorded files to
// scene-flow files, visualisations and a run summary.
#include <linux/videodev2.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/model_notes.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/log.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/source_chain.h"
#include "sfrt/pipeline/sources.h"
#if SFRT_HAVE_ROS
#include "sfrt/ros/bag_sink.h"
#endif
#if SFRT_HAVE_ROS2
#include "bags/any_bag.h"
#include "sfrt/ros2/bag_sink.h"
#endif
#include "sfrt/run_config.h"
#include "sfrt/run_shards.h"
#include "sfrt/session_environment.h"
#include "sfrt/sha256.h"
#include "sfrt/shapes.h"
#include "sfrt/shard_args.h"
#include "sfrt/vocabulary/failure_policy.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "run";
#if !SFRT_HAVE_ROS
// --replay-bag and --record-bag in a build without ros/.
constexpr char kNoRosBagSupport[] =
    "this sfrt was built without ROS bag support (install librosbag-dev and libsensor-msgs-dev, "
    "then configure again)";
#endif

// How --replay-bag reads the bag it names (bags/any_bag.h: rosbag2, or ROS 1 when this build
// has ros/).
#if SFRT_HAVE_ROS2
using bags::BagFormat;
using bags::BagFormatOf;
#else
struct BagFormat {
  Result<pipeline::BagProbe> (*probe)(const pipeline::BagReplaySpec&) = nullptr;
  std::unique_ptr<pipeline::FrameSource> (*make)(const pipeline::BagReplaySpec&) = nullptr;
};
Result<BagFormat> BagFormatOf(const std::string& path) {
  return Status::Error("'" + path +
                       "': this sfrt was built without bag replay (ros2/ needs libzstd-dev "
                       "liblz4-dev libsqlite3-dev libyaml-cpp-dev; install them, then configure "
                       "again)");
}
#endif

struct RunArgs {
  std::string model;
  std::string camera;
  std::string sbs_camera;
  std::string replay;
  std::string replay_left;
  std::string replay_right;
  std::string replay_video;
  std::string replay_bag;
  std::string replay_bags;  // a folder of bags, each a unit
  std::string left_topic = "left/image_rect";
  std::string right_topic = "right/image_rect";
  std::string record_bag;
  bool record_bag_vis = false;
  bool record_bag_inputs = true;
  std::string record_bag_frame_id = "left_camera";
  std::string pass = "clean";
  bool right_first = false;
  std::string format = "auto";
  std::string camera_size = "480x640";
  double fps = 30;
  int buffers = 4;
  double pair_tolerance_ms = 0;
  int camera_timeout_ms = 1000;
  std::string calibration;
  std::string on_bad_frame;
  std::string on_output_error = "stop";
  int64_t loop = 1;
  std::string latency_log;
  std::string out;
  std::string flow_format = "pfm";
  bool no_png = false;
  bool no_summary = false;
  std::string video;
  double video_fps = 10;
  std::string vis_scale;  // "" = first with --video, auto without
  double budget_ms = 0;
  int64_t max_frames = 0;
  double replay_fps = 0;
  std::string size;
  bool allow_aspect_change = false;
  std::string isa = "auto";
  int threads = 1;
  std::string queue;
  int queue_depth = 1;
  int picture_queue = -1;  // -1: the pipeline's default (2 for cameras, 0 for replays)
  std::string progress = "auto";
  int progress_every = 10;
  std::string shard;    // --shard I/N or auto
  int shard_count = 0;  // --shard-count (Kubernetes Indexed Jobs)
};

// --record-bag: a ROS 1 bag for a ".bag" path, else a rosbag2 bag (a .mcap file or a new
// folder), as this build has them. Checked before the run (CheckRecordBag), made after.
bool RecordsRos1Bag(const std::string& path) {
  return std::filesystem::path(path).extension() == ".bag";
}

Status CheckRecordBag(const std::string& path) {
  if (RecordsRos1Bag(path)) {
#if SFRT_HAVE_ROS
    Result<std::string> bag = ros::ResolveBagPath(path);
    return bag.ok() ? Status::Ok() : bag.status();
#else
    return Status::Error(std::string("--record-bag '") + path + "': " + kNoRosBagSupport);
#endif
  }
#if SFRT_HAVE_ROS2
  return ros2::CheckBag2Path(path);
#else
  return Status::Error("--record-bag '" + path +
                       "' is a rosbag2 bag (a .mcap file or a folder; a ROS 1 bag ends in "
                       ".bag): this sfrt was built without rosbag2 support (install "
                       "libzstd-dev liblz4-dev libsqlite3-dev, then configure again)");
#endif
}

// The sink of a path CheckRecordBag accepted.
std::unique_ptr<pipeline::FlowSink> MakeBagRecorder(const RunArgs& args,
                                                    const pipeline::VisualizerOptions& vis) {
  pipeline::FlowRecordingOptions o;
  o.path = args.record_bag;
  o.frame_id = args.record_bag_frame_id;
  o.vis = args.record_bag_vis;
  o.vis_options = vis;
  o.left_topic = pipeline::AbsoluteTopic(args.left_topic);  // a bag replayed keeps its topics
  o.right_topic = pipeline::AbsoluteTopic(args.right_topic);
#if SFRT_HAVE_ROS
  if (RecordsRos1Bag(args.record_bag)) return std::make_unique<ros::FlowBagSink>(o);
#endif
#if SFRT_HAVE_ROS2
  return std::make_unique<ros2::FlowBag2Sink>(o);
#else
  return nullptr;  // CheckRecordBag refused it
#endif
}

std::vector<std::string> SplitComma(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// What the command line says about the source, checked (ParseSourceFlags).
struct SourceFlags {
  bool live = false;                 // --camera or --sbs-camera
  bool plain = false;                // --replay-left/--replay-right
  std::vector<std::string> devices;  // --camera's two
  int cam_h = 0;
  int cam_w = 0;
  uint32_t fourcc = 0;  // --format; 0: auto
  camera::BadFramePolicy on_bad = camera::BadFramePolicy::kStop;
  std::optional<ShardSpec> shard;  // --shard
};

// The source flags: exactly one source, its devices, sizes, format and bad-frame policy. A usage
// error's message, or "".
std::string ParseSourceFlags(const RunArgs& args, SourceFlags* flags) {
  flags->plain = !args.replay_left.empty() || !args.replay_right.empty();
  flags->live = !args.camera.empty() || !args.sbs_camera.empty();
  if (args.model.empty() || args.out.empty()) {
    return "--model and --out are required (or a --config profile)";
  }
  const int sources = !args.camera.empty() + !args.sbs_camera.empty() + !args.replay.empty() +
                      flags->plain + !args.replay_video.empty() + !args.replay_bag.empty() +
                      !args.replay_bags.empty();
  if (sources != 1) {
    return sources == 0 ? "no source: give one of --camera, --sbs-camera, --replay, "
                          "--replay-left/--replay-right, --replay-video, --replay-bag, "
                          "--replay-bags"
                        : "give exactly one source (--camera, --sbs-camera, "
                          "--replay, --replay-left/--replay-right, --replay-video, "
                          "--replay-bag, --replay-bags)";
  }
  if ((!args.replay_bag.empty() || !args.replay_bags.empty()) && args.loop != 1) {
    return "--loop: passes over a bag are not supported; give --loop 1";
  }
  if (!args.shard.empty()) {
    if (args.replay.empty() && args.replay_bags.empty()) {
      return "--shard splits a dataset's sequences or a folder's bags between machines: it "
             "needs --replay DATASET or --replay-bags FOLDER";
    }
    if (args.loop != 1) return "--loop: a shard passes over its sequences once; give --loop 1";
    Result<ShardSpec> shard = ParseShardFlag(args.shard, args.shard_count);
    if (!shard.ok()) return shard.message();
    flags->shard = *shard;
  } else if (args.shard_count != 0) {
    return "--shard-count goes with --shard auto";
  }
  if (flags->plain && (args.replay_left.empty() || args.replay_right.empty())) {
    return "--replay-left and --replay-right go together";
  }
  flags->devices = SplitComma(args.camera);
  if (!args.camera.empty() && flags->devices.size() != 2) {
    return "--camera: expected two devices LEFT,RIGHT (e.g. /dev/video0,/dev/video2), "
           "got '" +
           args.camera + "'";
  }
  if (!ParseSize(args.camera_size, &flags->cam_h, &flags->cam_w)) {
    return "--camera-size: expected HxW (e.g. 480x640), got '" + args.camera_size + "'";
  }
  if (args.format != "auto") {
    if (args.format.size() != 4) {
      return "--format: expected auto or a fourcc (YUYV, MJPG, GREY, NV12, BGR3, "
             "RGB3), got '" +
             args.format + "'";
    }
    flags->fourcc = v4l2_fourcc(args.format[0], args.format[1], args.format[2], args.format[3]);
  }
  flags->on_bad = flags->live ? camera::BadFramePolicy::kSkip : camera::BadFramePolicy::kStop;
  if (!args.on_bad_frame.empty()) {
    auto parsed = camera::ParseBadFramePolicy(args.on_bad_frame);
    if (!parsed.ok()) {
      return "--on-bad-frame: expected skip or stop, got '" + args.on_bad_frame + "'";
    }
    flags->on_bad = *parsed;
  }
  return "";
}

// The flags that set pipeline options before anything is opened: size, flow format, ISA, queue,
// progress, the limits and bounds every value has, the pictures' scale. A usage error's
// message, or "".
std::string ParseOptionFlags(const RunArgs& args, const SourceFlags& flags,
                             pipeline::PipelineOptions* options) {
  if (!args.size.empty() && !ParseSize(args.size, &options->height, &options->width)) {
    return "--size: expected HxW (e.g. 540x960), got '" + args.size + "'";
  }
  if (const std::optional<config::FlowFormat> format =
          config::FlowFormatFromName(args.flow_format)) {
    options->flow_format = *format;
  } else if (args.flow_format == "none") {
    options->write_flow = false;
  } else {
    return "--flow-format: expected pfm, npy or none, got '" + args.flow_format + "'";
  }
  if (args.isa != "auto" && (!ParseIsa(args.isa, &options->isa) || options->isa == Isa::kAuto)) {
    return "--isa: '" + args.isa + "' is not one of " + IsaNameList(true);
  }
  if (options->isa != Isa::kAuto && !IsaSupported(options->isa)) {
    return "--isa " + args.isa + ": this CPU (or this build) cannot run it; it runs " +
           SupportedIsaList();
  }
  if (!args.queue.empty()) {
    if (args.queue == "newest-wins") {
      options->policy = pipeline::QueuePolicy::kNewestWins;
    } else if (args.queue == "block") {
      options->policy = pipeline::QueuePolicy::kBlock;
    } else {
      return "--queue: expected newest-wins or block, got '" + args.queue + "'";
    }
  }
  if (args.progress == "auto") {
    options->progress = pipeline::ProgressMode::kAuto;
  } else if (args.progress == "tty") {
    options->progress = pipeline::ProgressMode::kTty;
  } else if (args.progress == "lines") {
    options->progress = pipeline::ProgressMode::kLines;
  } else if (args.progress == "off") {
    options->progress = pipeline::ProgressMode::kOff;
  } else {
    return "--progress: expected auto, tty, lines or off, got '" + args.progress + "'";
  }
  for (const std::string& problem :
       {args.size.empty()
            ? std::string()
            : config::CheckSize(config::kInputSide, "--size", options->height, options->width),
        flags.live
            ? config::CheckSize(config::kFrameSide, "--camera-size", flags.cam_h, flags.cam_w)
            : "",
        config::CheckRange(config::kThreads, "--threads", args.threads),
        flags.live ? config::CheckRange(config::kCameraBuffers, "--buffers", args.buffers) : ""}) {
    if (!problem.empty()) return problem;
  }
  // Each bound names its option (the values may come from a profile as well).
  for (const std::string& problem :
       {CheckAtLeast("--max-frames", static_cast<double>(args.max_frames), 0),
        CheckAtLeast("--budget-ms", args.budget_ms, 0),
        CheckAtLeast("--pair-tolerance-ms", args.pair_tolerance_ms, 0),
        CheckAtLeast("--queue-depth", static_cast<double>(args.queue_depth), 1),
        CheckAtLeast("--fps", args.fps, 0),
        CheckAbove("--camera-timeout-ms", static_cast<double>(args.camera_timeout_ms), 0),
        CheckAbove("--video-fps", args.video_fps, 0)}) {
    if (!problem.empty()) return problem;
  }

  {  // the pictures' colour scale
    const std::string vis_scale = !args.vis_scale.empty() ? args.vis_scale
                                  : args.video.empty()    ? std::string("auto")
                                                          : std::string("first");
    Result<pipeline::VisScale> scale = pipeline::ParseVisScale(vis_scale);
    if (!scale.ok()) return scale.message();
    options->vis_scale = *scale;
  }

  return "";
}

// Everything that can be checked before the output directory is created or the source opened,
// so that a run that cannot start writes nothing: the model, --out, the output files, the
// calibration, the size against the model, the flow format against its output, --record-bag.
// kExitOk, or the exit code after reporting.
int CheckRunInputs(const RunArgs& args, pipeline::PipelineOptions* options,
                   std::shared_ptr<const Model>* model) {
  if (std::string problem = CheckInputFile(args.model, "model file"); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }
  if (std::string problem = CheckWritableDirectory(args.out, "--out"); !problem.empty()) {
    return ReportError(kName, problem, kExitUsage);
  }
  // The AVI writer takes only a regular file; the latency log may be a device or FIFO too.
  if (!args.video.empty()) {
    if (Result<std::string> video = pipeline::ResolveVideoPath(args.video); !video.ok()) {
      return ReportError(kName, video.message(), kExitUsage);
    }
  }
  for (const auto& [flag, path] :
       {std::pair<const char*, const std::string&>{"--video", args.video},
        {"--latency-log", args.latency_log}}) {
    if (path.empty()) continue;
    Result<io::OutputTarget> target = io::ResolveOutputTarget(path);
    if (!target.ok()) {
      return ReportError(kName, std::string(flag) + ": " + target.message(), kExitUsage);
    }
    // A device or FIFO is written in place: there is no directory to create a file in.
    if (target->kind != io::OutputTarget::Kind::kReplace) continue;
    const std::string parent = std::filesystem::path(target->path).parent_path().string();
    if (std::string problem = CheckWritableDirectory(parent.empty() ? "." : parent, flag);
        !problem.empty()) {
      return ReportError(kName, problem, kExitUsage);
    }
  }
  if (!args.calibration.empty()) {
    std::vector<std::string> files = SplitComma(args.calibration);
    for (const std::string& f : files) {
      if (std::string problem = CheckInputFile(f, "--calibration file"); !problem.empty()) {
        return ReportError(kName, problem, kExitFailure);
      }
    }
    auto calib = camera::ReadStereoCalibration(files);
    if (!calib.ok()) return ReportError(kName, calib.message(), kExitFailure);
    options->calibration = std::move(calib).value();
  }
  Result<std::shared_ptr<const Model>> loaded = Model::LoadFile(args.model);
  if (!loaded.ok()) return ReportError(kName, loaded.message(), kExitFailure);
  *model = *loaded;
  if (!args.size.empty()) {
    if (auto geometry = InferGeometry(**loaded, options->height, options->width); !geometry.ok()) {
      return ReportError(kName, "--size " + args.size + ": " + geometry.message(), kExitUsage);
    }
  }
  // Options that cannot work with this model or path are usage errors, found before the output
  // directory is made or a frame read (the pipeline would only find them at its setup).
  const int channels = (*loaded)->metadata().output.channels;
  if (options->write_flow && options->flow_format == pipeline::FlowFormat::kPfm && channels > 0 &&
      channels != 1 && channels != 3) {
    return ReportError(kName,
                       args.model + " outputs " + std::to_string(channels) +
                           " channels; PFM holds 1 or 3 (use --flow-format npy)",
                       kExitUsage);
  }
  if (!args.record_bag.empty()) {
    if (Status s = CheckRecordBag(args.record_bag); !s.ok()) {
      return ReportError(kName, s.message(), kExitUsage);
    }
  }
  return kExitOk;
}

// The run's source, and what --profile-overhead needs to open it again.
struct RunSource {
  std::unique_ptr<pipeline::FrameSource> source;
  std::optional<pipeline::ReplaySpec> replay;
  std::optional<pipeline::BagReplaySpec> bag;
  BagFormat bag_format;
  std::optional<RunShardPlan> shard;  // --shard: the units this shard reads, where it writes
  // --replay-bags: a fresh chain of the same bags (for --profile-overhead's second run).
  std::function<std::unique_ptr<pipeline::FrameSource>()> remake;
};

// --replay-bag's spec for the bag at `path`.
pipeline::BagReplaySpec BagSpec(const RunArgs& args, const SourceFlags& flags,
                                const std::string& path) {
  pipeline::BagReplaySpec spec;
  spec.path = path;
  spec.left_topic = args.left_topic;
  spec.right_topic = args.right_topic;
  spec.pair_tolerance_ms = args.pair_tolerance_ms > 0 ? args.pair_tolerance_ms : 8.0;
  spec.on_bad_frame = flags.on_bad;
  return spec;
}

// The bags directly in `folder`, sorted by name: .mcap, .db3 and .bag files, and folders holding
// a rosbag2 metadata.yaml.
Result<std::vector<std::string>> ListBags(const std::string& folder) {
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    return Status::Error("'" + folder + "' is not a folder");
  }
  std::vector<std::string> bags;
  std::filesystem::directory_iterator it(folder, ec);
  for (; !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
    const std::filesystem::path& p = it->path();
    const std::string ext = p.extension().string();
    std::error_code not_a_bag;  // e.g. a plain file has no metadata.yaml under it
    const bool file =
        it->is_regular_file(not_a_bag) && (ext == ".mcap" || ext == ".db3" || ext == ".bag");
    if (file || std::filesystem::is_regular_file(p / "metadata.yaml", not_a_bag)) {
      bags.push_back(p.filename().string());
    }
  }
  if (ec) return Status::Error("'" + folder + "': " + ec.message());
  if (bags.empty()) {
    return Status::Error("'" + folder +
                         "' holds no bag (.mcap, .db3 or .bag files, or rosbag2 "
                         "folders with metadata.yaml)");
  }
  std::sort(bags.begin(), bags.end());
  return bags;
}

// --replay-bags: the folder's bags (this shard's with --shard), each probed, replayed one after
// another as units named by their file names. kExitOk, or the exit code after reporting.
int OpenBagFolder(const RunArgs& args, const SourceFlags& flags, RunSource* out) {
  Result<std::vector<std::string>> bags = ListBags(args.replay_bags);
  if (!bags.ok()) return ReportError(kName, "--replay-bags: " + bags.message(), kExitUsage);
  const std::string topics = "(" + pipeline::AbsoluteTopic(args.left_topic) + ", " +
                             pipeline::AbsoluteTopic(args.right_topic) + ")";
  std::string description =
      std::to_string(bags->size()) + " bag(s) in " + args.replay_bags + " " + topics;
  std::vector<std::string> units = *bags;
  if (flags.shard) {
    Result<RunShardPlan> plan = PlanRunShard(*bags, description, "bag", *flags.shard, args.out);
    if (!plan.ok()) return ReportError(kName, "--replay-bags: " + plan.message(), kExitUsage);
    units = plan->mine;
    description = std::to_string(units.size()) + " of " + std::to_string(bags->size()) +
                  " bag(s) in " + args.replay_bags + " " + topics;
    out->shard = std::move(plan).value();
  }
  std::vector<pipeline::SourceUnit> chain;
  for (const std::string& unit : units) {
    const pipeline::BagReplaySpec spec =
        BagSpec(args, flags, (std::filesystem::path(args.replay_bags) / unit).string());
    Result<BagFormat> format = BagFormatOf(spec.path);
    if (!format.ok()) return ReportError(kName, "--replay-bags: " + format.message(), kExitUsage);
    if (Result<pipeline::BagProbe> probe = format->probe(spec); !probe.ok()) {
      return ReportError(kName, "--replay-bags: " + probe.message(), kExitUsage);
    }
    chain.push_back({unit, [spec, make = format->make] { return make(spec); }});
  }
  out->remake = [chain, description] {
    return pipeline::MakeSourceChain(chain, description, "replay-bags");
  };
  out->source = out->remake();
  return kExitOk;
}

// Opens the source the flags name (cameras, a bag, or files), each probed first. kExitOk, or the
// exit code after reporting.
int OpenRunSource(const RunArgs& args, const SourceFlags& flags, RunSource* out) {
  std::error_code ec;
  if (flags.live) {
    v4l2::StereoConfig config;
    config.mode = args.camera.empty() ? v4l2::StereoConfig::Mode::kSideBySide
                                      : v4l2::StereoConfig::Mode::kTwoDevices;
    config.left.device = args.camera.empty() ? args.sbs_camera : flags.devices[0];
    config.left.pixel_format = flags.fourcc;
    config.left.width =
        config.mode == v4l2::StereoConfig::Mode::kSideBySide ? 2 * flags.cam_w : flags.cam_w;
    config.left.height = flags.cam_h;
    config.left.fps = args.fps;
    config.left.buffer_count = args.buffers;
    config.left.watchdog_ms = args.camera_timeout_ms;
    config.right = config.left;
    if (!args.camera.empty()) {
      config.right.device = flags.devices[1];
      config.right.width = flags.cam_w;
    }
    // Default pairing tolerance: under half a frame period (0.45 of it), at most 8 ms... unless
    // the frame rate is unknown (--fps 0), then 8 ms.
    config.pair_tolerance_ns =
        args.pair_tolerance_ms > 0
            ? static_cast<int64_t>(args.pair_tolerance_ms * 1e6)
            : (args.fps > 0 ? static_cast<int64_t>(0.45e9 / args.fps) : int64_t{8'000'000});
    config.sbs_left_first = !args.right_first;
    config.timeout_ms = args.camera_timeout_ms;
    out->source = pipeline::MakeCameraSource(config, flags.on_bad);
  } else if (!args.replay_bags.empty()) {
    return OpenBagFolder(args, flags, out);
  } else if (!args.replay_bag.empty()) {
    const pipeline::BagReplaySpec spec = BagSpec(args, flags, args.replay_bag);
    if (!std::filesystem::is_directory(spec.path, ec)) {
      if (std::string problem = CheckInputFile(spec.path, "--replay-bag file"); !problem.empty()) {
        return ReportError(kName, problem, kExitFailure);
      }
    }
    Result<BagFormat> format = BagFormatOf(spec.path);
    if (!format.ok()) return ReportError(kName, "--replay-bag: " + format.message(), kExitUsage);
    if (Result<pipeline::BagProbe> probe = format->probe(spec); !probe.ok()) {
      return ReportError(kName, "--replay-bag: " + probe.message(), kExitUsage);
    }
    out->bag = spec;
    out->bag_format = *format;
    out->source = out->bag_format.make(spec);
  } else {
    pipeline::ReplaySpec spec;
    if (!args.replay.empty()) {
      spec.kind = pipeline::ReplaySpec::Kind::kDataset;
      spec.root = args.replay;
      if (!std::filesystem::exists(spec.root, ec)) {
        return ReportError(kName, "--replay: dataset root '" + spec.root + "' does not exist",
                           kExitFailure);
      }
      if (flags.shard) {
        Result<RunShardPlan> plan = PlanDatasetShard(spec.root, args.pass, *flags.shard, args.out);
        if (!plan.ok()) return ReportError(kName, "--replay: " + plan.message(), kExitUsage);
        spec.sequences = plan->mine;
        out->shard = std::move(plan).value();
      }
    } else if (flags.plain) {
      spec.kind = pipeline::ReplaySpec::Kind::kPlain;
      spec.left = args.replay_left;
      spec.right = args.replay_right;
    } else {
      spec.kind = pipeline::ReplaySpec::Kind::kVideo;
      spec.video = args.replay_video;
      if (std::string problem = CheckInputFile(spec.video, "--replay-video file");
          !problem.empty()) {
        return ReportError(kName, problem, kExitFailure);
      }
    }
    spec.pass = args.pass;
    spec.video_left_first = !args.right_first;
    spec.on_bad_frame = flags.on_bad;
    spec.loops = args.loop;
    const char* flag = !args.replay.empty() ? "--replay"
                       : flags.plain        ? "--replay-left/--replay-right"
                                            : "--replay-video";
    if (Result<int64_t> probe = pipeline::ProbeReplay(spec); !probe.ok()) {
      return ReportError(kName, std::string(flag) + ": " + probe.message(), kExitUsage);
    }
    out->replay = spec;
    out->source = pipeline::MakeReplaySource(spec);
  }
  return kExitOk;
}

// The flags that only set options (checked already).
void SetRunOptions(const RunArgs& args, pipeline::PipelineOptions* options) {
  options->out_dir = args.out;
  options->allow_aspect_change = args.allow_aspect_change;
  options->on_output_error = *vocabulary::FailurePolicyFromName(args.on_output_error);
  options->write_png = !args.no_png;
  options->write_summary = !args.no_summary;
  options->video_path = args.video;
  options->video_fps = args.video_fps;
  options->budget_ms = args.budget_ms;
  options->max_frames = args.max_frames;
  options->source_fps = args.replay_fps;
  options->threads = args.threads;
  options->queue_capacity = static_cast<size_t>(args.queue_depth);
  if (args.picture_queue >= 0) options->picture_queue = static_cast<size_t>(args.picture_queue);
  options->progress_every = args.progress_every;
  options->model_path = args.model;
  options->latency_log = args.latency_log;
}

// The ISA the run will use, from --isa, the profile or SFRT_ISA: refused before the run when this
// CPU cannot run it or the model's precision needs kernels it lacks. kExitOk, or the exit code
// after reporting.
int CheckRunIsa(const RunArgs& args, const Model& model, pipeline::PipelineOptions* options) {
  // SFRT_ISA (when neither --isa nor the profile chose one) and the kernel switches.
  if (Status env = tools::ApplySessionEnvironment(options->isa, options->tuning); !env.ok()) {
    return ReportError(kName, env.message(), kExitUsage);
  }
  // An ISA from SFRT_ISA (or the profile) gets the same check as --isa: refused before the run.
  if (options->isa != Isa::kAuto && !IsaSupported(options->isa)) {
    return ReportError(kName,
                       std::string("ISA ") + IsaName(options->isa) +
                           " (from --isa, the profile or SFRT_ISA): this CPU (or this build) "
                           "cannot run it; it runs " +
                           SupportedIsaList(),
                       kExitUsage);
  }
  if (std::string problem = ForcedIsaPrecisionProblem(model, options->isa); !problem.empty()) {
    return ReportError(kName,
                       args.model + ": " + problem + " (ISA " + IsaName(options->isa) +
                           " from --isa, the profile or SFRT_ISA)",
                       kExitFailure);
  }
  return kExitOk;
}

// --shard: the shard's folder, every latency sample and the shard's record in its summary (so
// that sfrt merge gives the single run's), its status file, and a line saying what it reads.
// kExitOk, or the exit code after reporting.
int SetShardOptions(const RunArgs& args, const RunShardPlan& plan,
                    const pipeline::FrameSource* source, std::optional<ShardProgress>* progress,
                    pipeline::PipelineOptions* options) {
  Result<std::string> sha = Sha256OfFile(args.model);
  if (!sha.ok()) return ReportError(kName, args.model + ": " + sha.message(), kExitFailure);
  std::error_code ec;
  std::filesystem::create_directories(plan.dir, ec);  // before the status file is written in it
  options->out_dir = plan.dir;
  options->summary_samples = true;
  options->annotate_summary = [plan, sha = *sha](nlohmann::json* summary) {
    AnnotateRunShard(plan, sha, summary);
  };
  const std::string name = ShardName(plan.shard.index, plan.shard.count);
  progress->emplace(name, /*quiet=*/true,
                    (std::filesystem::path(plan.dir) / "status.json").string());
  options->after_window = [progress, source, written = 0](const pipeline::FrameMeta& m) mutable {
    ++written;
    const int total = static_cast<int>(source->total_windows().value_or(0));
    (*progress)->Update(written, total, m.sequence);  // no allocation on the output stage
  };
  std::cout << "shard       " << name << ": " << plan.mine.size() << " of "
            << plan.list.units.size() << " units (list " << plan.list.sha256.substr(0, 12)
            << "), written to " << plan.dir << " (sfrt merge " << plan.out << " gives the run's "
            << "summary)\n";
  return kExitOk;
}

int RunRun(const RunArgs& args, RunConfigState* rc) {
  // Installed first and kept until the process exits: a signal while the model loads or the
  // camera opens stops the run before its first frame, and one that lands after the pipeline
  // has finished only sets a flag nobody reads any more; either way the summary is printed.
  const StopSignals stop_signals = CatchStopSignals();
  // Usage checks, before any file or device is touched.
  SourceFlags flags;
  pipeline::PipelineOptions options;
  if (std::string usage = ParseSourceFlags(args, &flags); !usage.empty()) {
    return ReportError(kName, usage, kExitUsage);
  }
  if (std::string usage = ParseOptionFlags(args, flags, &options); !usage.empty()) {
    return ReportError(kName, usage, kExitUsage);
  }
  std::shared_ptr<const Model> model;
  if (int code = CheckRunInputs(args, &options, &model); code != kExitOk) return code;
  RunSource run_source;
  if (int code = OpenRunSource(args, flags, &run_source); code != kExitOk) return code;
  std::unique_ptr<pipeline::FrameSource>& source = run_source.source;
  SetRunOptions(args, &options);
  std::optional<ShardProgress> shard_progress;
  if (run_source.shard) {
    if (int code =
            SetShardOptions(args, *run_source.shard, source.get(), &shard_progress, &options);
        code != kExitOk) {
      return code;
    }
  }
  std::error_code ec;
  std::filesystem::create_directories(options.out_dir, ec);
  if (!std::filesystem::is_directory(options.out_dir, ec)) {
    return ReportError(kName, "--out: cannot create the output directory '" + options.out_dir + "'",
                       kExitFailure);
  }
  options.stop = stop_signals.stop;
  pipeline::StderrLog log("sfrt run");  // the library's warnings, notes and progress
  options.log = &log;
  std::unique_ptr<pipeline::FlowSink> bag_sink;
  if (!args.record_bag.empty()) {
    bag_sink = MakeBagRecorder(args, {options.vis_scale, model->metadata().output.units});
    options.sinks.push_back(bag_sink.get());
    auto* inputs = dynamic_cast<pipeline::InputRecorder*>(bag_sink.get());
    if (args.record_bag_inputs && inputs != nullptr) {
      source = pipeline::MakeRecordingSource(std::move(source), inputs);
    }
  }
  options.stop_signal = stop_signals.signal;
  if (int code = ConfigurePipeline(rc, &options); code != kExitOk) return code;
  if (int code = CheckRunIsa(args, *model, &options); code != kExitOk) return code;

  std::function<std::unique_ptr<pipeline::FrameSource>()> again;
  if (run_source.replay) {
    again = [&run_source] { return pipeline::MakeReplaySource(*run_source.replay); };
  }
  if (run_source.bag) {
    again = [&run_source] { return run_source.bag_format.make(*run_source.bag); };
  }
  if (run_source.remake) again = run_source.remake;
  // Every check has passed: the note belongs to a run that starts.
  if (std::string notice = UntrainedNotice(args.model, model->metadata().training);
      !notice.empty()) {
    std::cout << notice << "\n";
  }
  if (std::string notice = PrecisionFallbackNotice(*model, options.isa); !notice.empty()) {
    std::cout << notice << "\n";
  }
  pipeline::PipelineResult result = RunConfiguredPipeline(rc, model, source.get(), options, again);
  if (!result.started) {  // nothing ran: no statistics to show
    return ReportError(kName, result.status.message(),
                       result.usage_error ? kExitUsage : kExitFailure);
  }
  PrintRunResult(source->Describe(), result);
  PrintRunConfigReport(*rc, result, std::cout);
  if (shard_progress) {
    if (result.status.ok()) shard_progress->Done(static_cast<int>(result.frames));
    if (!result.status.ok()) shard_progress->Failed(result.status.message());
  }
  if (!result.status.ok()) return ReportError(kName, result.status.message(), kExitFailure);
  if (rc->profile_write_failed) {  // asked for and measured, but lost: not a success
    return ReportError(kName, "--profile: " + rc->profile_error, kExitFailure);
  }
  return kExitOk;
}

}  // namespace

// The help text after the options.
constexpr char kRunFooter[] =
    "Stages (source, preprocess, infer, output) run on their own threads joined by\n"
    "bounded queues. The network sees (pair t, pair t+1) windows, preprocessed as the model's\n"
    "metadata says. Latencies are measured on CLOCK_MONOTONIC from capture (the V4L2 buffer\n"
    "timestamp; for files, the end of reading) to the written output. SIGINT/SIGTERM stop the\n"
    "source; frames already read are finished, every file is written to a temporary name and\n"
    "renamed, and summary.json says how far the run got. Exit codes: 0 success (also after a\n"
    "stop by signal), 1 runtime or input failure (incl. a bad frame under --on-bad-frame\n"
    "stop), 2 usage error (incl. an invalid --config profile, and anything checked before the\n"
    "first frame: an ISA this CPU cannot run, a --size outside 16..4096 per side or one the\n"
    "model cannot take, an --out where files cannot be created, an empty replay folder, left\n"
    "and right folders with different frame counts; then nothing is written).\n"
    "With --config FILE the profile gives every option above it has a key for (the start\n"
    "banner lists them); an option given on the command line overrides the profile. The final\n"
    "summary lists the settings applied and not applied.";

// The model, the source (cameras, files, a video, a bag) and the bag to record.
void AddSourceOptions(CLI::App* cmd, RunArgs* args) {
  cmd->add_option("--model", args->model, "Model file (.sfrt); required unless --config");
  cmd->add_option("--camera", args->camera,
                  "Two V4L2 devices LEFT,RIGHT, paired by capture timestamp");
  cmd->add_option("--sbs-camera", args->sbs_camera,
                  "One V4L2 device delivering both views side by side");
  cmd->add_option("--replay", args->replay,
                  "Dataset root: Scene Flow (FlyingThings3D/Driving/Monkaa), KITTI scene flow, "
                  "or <seq>/{left,right}/ directories (layout detected)");
  cmd->add_option("--replay-left", args->replay_left,
                  "Left frames: a directory or a glob, sorted by name (with --replay-right)");
  cmd->add_option("--replay-right", args->replay_right, "Right frames: a directory or a glob");
  cmd->add_option("--replay-video", args->replay_video,
                  "Side-by-side stereo video file (OpenCV VideoCapture)");
  cmd->add_option(
      "--replay-bag", args->replay_bag,
      "A bag: rosbag2 (a folder from `ros2 bag record`, a .mcap or a .db3 file) or ROS 1 "
      "(.bag). sensor_msgs Image (bgr8, rgb8, bgra8, rgba8, mono8) or CompressedImage (JPEG, "
      "PNG) on --left-topic and --right-topic, paired by header stamp within "
      "--pair-tolerance-ms (default 8); unpaired frames are counted in the summary. ROS 1 bags "
      "need a build with librosbag");
  cmd->add_option(
      "--replay-bags", args->replay_bags,
      "A folder of bags (.mcap, .db3 and .bag files, and rosbag2 folders with metadata.yaml), "
      "replayed one after another in name order as --replay-bag replays one; each bag is a "
      "sequence of its own (no window spans two; outputs <bag>_<frame>), and the unit of "
      "--shard. Their images must have one size");
  cmd->add_option("--left-topic", args->left_topic, "--replay-bag(s): the left image topic")
      ->capture_default_str();
  cmd->add_option("--right-topic", args->right_topic, "--replay-bag(s): the right image topic")
      ->capture_default_str();
  cmd->add_option("--record-bag", args->record_bag,
                  "Also write the flow as a bag: rosbag2 for a .mcap file or a new folder (MCAP, "
                  "as ros2 bag record writes it), ROS 1 for a .bag file. /flow (Image 32FC3, dX "
                  "dY dZ per pixel of the left image at t, stamped with pair t), /flow_t1 "
                  "(Header stamped with pair t+1), /flow_vis with --record-bag-vis, and the "
                  "stereo pairs read on --left-topic and --right-topic (Image bgr8); written "
                  "under a temporary name and renamed when complete (docs/ros.md)");
  cmd->add_flag("--record-bag-vis", args->record_bag_vis,
                "--record-bag: also the visualisation as /flow_vis (bgr8)");
  cmd->add_flag("!--record-bag-flow-only", args->record_bag_inputs,
                "--record-bag: leave the input images out (the flow messages only)");
  cmd->add_option("--record-bag-frame-id", args->record_bag_frame_id,
                  "--record-bag: header.frame_id of the messages (the left camera's frame)")
      ->capture_default_str();
}

// How the source is read: passes, formats and sizes, pairing, calibration, bad frames.
void AddInputOptions(CLI::App* cmd, RunArgs* args) {
  cmd->add_option("--pass", args->pass,
                  "Scene Flow datasets: rendering pass to read, clean or final")
      ->capture_default_str();
  cmd->add_flag("--right-first", args->right_first,
                "Side-by-side sources: the left half is the right view");
  cmd->add_option("--format", args->format,
                  "Camera pixel format: auto (the first the device lists that sfrt converts) or "
                  "a fourcc: YUYV, MJPG, GREY, NV12, BGR3, RGB3")
      ->capture_default_str();
  cmd->add_option("--camera-size", args->camera_size,
                  "Camera image size per view, HxW (the driver may adjust it; the summary says)")
      ->capture_default_str();
  cmd->add_option("--fps", args->fps, "Camera frame rate to request (0: the driver's)")
      ->capture_default_str();
  cmd->add_option("--buffers", args->buffers, "V4L2 buffers to request per camera (>= 2)")
      ->capture_default_str();
  cmd->add_option("--pair-tolerance-ms", args->pair_tolerance_ms,
                  "Two cameras: largest timestamp difference of a stereo pair (default: 0.45 "
                  "of the frame period, 8 ms when --fps is 0)");
  cmd->add_option("--camera-timeout-ms", args->camera_timeout_ms,
                  "Camera watchdog: no frame for this long is logged and counted")
      ->capture_default_str();
  cmd->add_option("--calibration", args->calibration,
                  "Stereo calibration to rectify with: ROS camera_info LEFT.yaml,RIGHT.yaml, a "
                  "Kalibr camchain, or OpenCV YAML (one or two files, comma-separated). "
                  "Without it frames are only resized. A calibration made at another "
                  "resolution than the frames' is an error (exit 1)");
  cmd->add_option("--on-bad-frame", args->on_bad_frame,
                  "A missing/corrupt frame: skip (recorded in the summary) or stop (exit 1). "
                  "Default: stop for replays, skip for cameras");
  cmd->add_option("--on-output-error", args->on_output_error,
                  "A window's output cannot be written (disk full, read-only directory): stop "
                  "(exit 1) or skip it (counted and listed in summary.json). Either way no "
                  "partial file is left")
      ->capture_default_str()
      ->check(CLI::IsMember(std::vector<std::string>(vocabulary::kFailurePolicyNames.begin(),
                                                     vocabulary::kFailurePolicyNames.end())));
  RequireAtLeast(cmd->add_option("--loop", args->loop,
                                 "Replays: pass over the files this many times (soak runs; "
                                 "later passes overwrite the same output files)")
                     ->capture_default_str(),
                 1);
  cmd->add_option(
      "--latency-log", args->latency_log,
      "Also write a CSV line per written window: window, source/preprocess/infer/"
      "output and end-to-end milliseconds, input size, and the time the window was done on "
      "CLOCK_MONOTONIC in ms (for soak runs). Written as the run goes; a device or FIFO "
      "(e.g. /dev/stdout) is written in place; a failed write is an output error "
      "(--on-output-error)");
}

// What the run writes: the directory, flow files, pictures, video, summary.
void AddOutputOptions(CLI::App* cmd, RunArgs* args) {
  cmd->add_option("--out", args->out,
                  "Output directory (created): <stem>.pfm|.npy flow, <stem>.png visualisation, "
                  "summary.json (unless --no-summary); required unless --config");
  cmd->add_option("--flow-format", args->flow_format,
                  "Flow files: pfm (3-channel PFM), npy (float32 (H,W,3)) or none")
      ->capture_default_str();
  cmd->add_flag("--no-png", args->no_png, "Do not write visualisation PNGs");
  cmd->add_flag("--no-summary", args->no_summary,
                "Do not write summary.json (the console summary is still printed)");
  cmd->add_option("--video", args->video,
                  "Also write the visualisations as an MJPG AVI video to this file (a regular "
                  "file, replaced at the end; a symbolic link is followed and kept)");
  cmd->add_option("--video-fps", args->video_fps, "Frame rate written into --video")
      ->capture_default_str();
  cmd->add_option("--vis-scale", args->vis_scale,
                  "Colour scale of the PNGs and --video: 'first' (set from the first frame, the "
                  "99th percentile of its |d|, then the same flow gets the same colour in every "
                  "frame), 'fixed:VALUE' (full colour at |d| = VALUE, in the model's units) or "
                  "'auto' (each frame's largest |d|). Default: first with --video, auto without");
}

// How the run is timed and computed: budget, pacing, size, ISA, threads, queues, progress.
void AddRunOptions(CLI::App* cmd, RunArgs* args) {
  cmd->add_option("--budget-ms", args->budget_ms,
                  "Deadline per frame, capture to written output; misses are counted (0: none)")
      ->capture_default_str();
  RequireAtLeast(cmd->add_option("--replay-fps", args->replay_fps,
                                 "Read replayed windows at this rate, like a camera (0: as fast "
                                 "as the pipeline takes them)"),
                 0);
  cmd->add_option("--max-frames", args->max_frames, "Stop after this many frames (0: no limit)")
      ->capture_default_str();
  cmd->add_option("--size", args->size,
                  "Model input size HxW (frames are rectified/resized to it; default: the size "
                  "a trained model records (its traced size, as sfrt inspect prints it), else the "
                  "source's frame size; "
                  "the run prints which)");
  cmd->add_flag("--allow-aspect-change", args->allow_aspect_change,
                "Take a --size of the inverse aspect of the frames (refused otherwise, as a "
                "likely WxH given for HxW)");
  cmd->add_option("--isa", args->isa,
                  "Kernels: auto (SFRT_ISA or the best this CPU runs), " + IsaNameList(false))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "Threads for inference, 0..256 (0: one per CPU)")
      ->capture_default_str();
  cmd->add_option("--queue", args->queue,
                  "When a stage falls behind: newest-wins (drop the older queued frame, counted) "
                  "or block (wait). Default: newest-wins for cameras, block for replays");
  cmd->add_option("--queue-depth", args->queue_depth, "Frames each queue between stages holds")
      ->capture_default_str();
  cmd->add_option("--picture-queue", args->picture_queue,
                  "Encode the PNGs and --video on a thread of their own behind a queue of N "
                  "windows, off the output stage (end to end then ends before them; their time is "
                  "printed apart, and for cameras and paced replays (--replay-fps) a picture that "
                  "cannot keep up is dropped and counted, never holding back the flow), or 0: on "
                  "the output stage, each window's files complete together. Default: 2 for "
                  "cameras and paced replays, 0 for unpaced replays")
      ->check(CLI::Validator(
          [](std::string& text) {
            int n = -1;
            return CLI::detail::lexical_cast(text, n) && n >= 0
                       ? std::string()
                       : text + " is not a whole number >= 0";
          },
          "", "count"));
  cmd->add_option("--progress", args->progress,
                  "Progress on stderr: auto (one updating line on a terminal, else lines), tty, "
                  "lines, off")
      ->capture_default_str();
  cmd->add_option("--progress-every", args->progress_every,
                  "With line progress: one line every this many frames")
      ->capture_default_str();
  cmd->add_option("--shard", args->shard,
                  "--replay only: replay shard I of N (I/N, 0-based) of the dataset's sorted "
                  "sequences (KITTI scenes; sequence k to shard k mod N, never split), or auto: "
                  "the scheduler's index (SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN of "
                  "SLURM_ARRAY_TASK_COUNT, or JOB_COMPLETION_INDEX of --shard-count). Its files "
                  "go to <out>/shard-I-of-N/, whose summary.json also holds the work list, the "
                  "model's SHA-256 and every latency sample, and status.json its progress; "
                  "sfrt merge <out> gives the single run's summary");
  cmd->add_option("--shard-count", args->shard_count,
                  "--shard auto with JOB_COMPLETION_INDEX (Kubernetes Indexed Jobs set no count)");
}

Command AddRunCommand(CLI::App& parent) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "run", "Run the real-time pipeline on cameras or recorded frames and write the scene flow");
  auto rc = std::make_shared<RunConfigState>();
  AddRunConfigOptions(cmd, rc.get());
  for (auto* add : {AddSourceOptions, AddInputOptions, AddOutputOptions, AddRunOptions}) {
    add(cmd, args.get());
  }
  cmd->footer(kRunFooter);
  return Command{cmd, [args, rc, cmd] {
                   if (int code = ApplyRunConfig(cmd, rc.get()); code != kExitOk) return code;
                   return RunRun(*args, rc.get());
                 }};
}

}  // namespace sfrt::tools
