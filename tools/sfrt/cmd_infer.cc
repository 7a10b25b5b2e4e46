// sfrt infer: one forward pass on four images (or a prepared .npy input); writes the flow.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "sfrt/camera/image_file.h"
#include "sfrt/camera/preprocess.h"
#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/model.h"
#include "sfrt/model_notes.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/pipeline/io/pfm.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/stats.h"
#include "sfrt/pipeline/window_input.h"
#include "sfrt/session.h"
#include "sfrt/session_environment.h"

namespace sfrt::tools {
namespace {

constexpr char kName[] = "infer";

struct InferArgs {
  std::string model;
  std::string left0;
  std::string right0;
  std::string left1;
  std::string right1;
  std::string color0;
  std::string depth0;
  std::string color1;
  std::string depth1;
  float depth_units = 1000.0f;
  std::string input_npy;
  std::string output;
  std::string size;
  bool allow_aspect_change = false;
};

struct InputTensor {
  int height = 0;
  int width = 0;
  std::vector<float> data;  // height x width x channels, in the model's channel order
  std::string description;  // where it came from, for the report
};

std::string SizeString(int height, int width) {
  return std::to_string(height) + "x" + std::to_string(width);
}

// One input file of a window: the flag naming it, its path and, once read, its pixels.
struct InputFile {
  const char* flag;
  const std::string* path;
  cv::Mat image;
};

// Reads `file` as 8-bit BGR.
Status ReadColourImage(InputFile& file) {
  if (std::string problem = CheckInputFile(*file.path, std::string(file.flag) + " image");
      !problem.empty()) {
    return Status::Error(problem);
  }
  if (std::string why = camera::ReadImageFile(*file.path, cv::IMREAD_COLOR, &file.image);
      !why.empty()) {
    return Status::Error(std::string(file.flag) + " image '" + *file.path + "' " + why);
  }
  if (file.image.type() != CV_8UC3) {
    return Status::Error(std::string(file.flag) + " image '" + *file.path +
                         "' did not decode to 8-bit BGR");
  }
  return Status::Ok();
}

// The four files' names for messages: "--left1 image 'b.png'".
std::array<std::string, 4> FileNames(const InputFile (&files)[4], const std::string& noun) {
  std::array<std::string, 4> names;
  for (size_t i = 0; i < 4; ++i)
    names[i] = std::string(files[i].flag) + noun + " '" + *files[i].path + "'";
  return names;
}

// The network input of the window read into `files`, as pipeline::WindowInput builds it (the
// size `sfrt run` would choose, its resize, the model's preprocessing); notes about the size on
// stderr.
Result<InputTensor> BuildInput(const ModelMetadata& meta, const pipeline::WindowInputOptions& opts,
                               const InputFile (&files)[4], const std::string& noun,
                               const char* rule) {
  Result<pipeline::WindowInput> window = pipeline::WindowInput::Create(meta, opts);
  if (!window.ok()) return window.status();
  const std::array<cv::Mat, 4> images = {files[0].image, files[1].image, files[2].image,
                                         files[3].image};
  if (Status ok = window->Check(images, FileNames(files, noun), rule); !ok.ok()) return ok;
  const int rows = images[0].rows;
  const int cols = images[0].cols;
  Result<pipeline::InputSizeChoice> chosen = window->ChooseSize(rows, cols);
  if (!chosen.ok()) return chosen.status();
  if (!window->rgbd() && (chosen->height != rows || chosen->width != cols)) {
    std::cerr << "sfrt infer: note: input size " << SizeString(chosen->height, chosen->width)
              << " (HxW): " << chosen->reason << std::endl;
  }
  if (!chosen->aspect_note.empty()) {
    std::cerr << "sfrt infer: warning: " << chosen->aspect_note << std::endl;
  }
  InputTensor input;
  input.height = chosen->height;
  input.width = chosen->width;
  input.data.resize(window->Floats(input.height, input.width));
  if (Status built = window->Build(images, input.height, input.width, input.data); !built.ok()) {
    return built;
  }
  input.description = window->description();
  if (input.height != rows || input.width != cols) {
    input.description += ", resized from " + SizeString(rows, cols);
  }
  return input;
}

// Reads the four images and builds the network input as the model's metadata prescribes:
// image order, color order, then value = (pixel * scale - mean[c]) / std[c].
Result<InputTensor> InputFromImages(const InferArgs& args, const ModelMetadata& meta, int resize_h,
                                    int resize_w) {
  InputFile sources[4] = {{"--left0", &args.left0, {}},
                          {"--right0", &args.right0, {}},
                          {"--left1", &args.left1, {}},
                          {"--right1", &args.right1, {}}};
  // Check the metadata before reading anything big: the same preprocessing as `sfrt run`
  // (camera/sources Preprocessor, parameters from the model's metadata).
  Result<camera::PreprocessParams> params = pipeline::PreprocessFromMetadata(meta.input);
  if (!params.ok()) {
    return Status::Error(params.message() + "; give --input-npy instead");
  }
  for (InputFile& s : sources) {
    if (Status read = ReadColourImage(s); !read.ok()) return read;
  }
  // One note for the run when an image is not 8-bit colour (read as 8-bit BGR all the same).
  for (const InputFile& s : sources) {
    camera::Result<camera::ImageHeader> header = camera::ReadImageHeader(*s.path);
    const std::string what = header.ok() ? camera::NotEightBitColour(*header) : "";
    if (what.empty()) continue;
    std::cerr << "sfrt infer: note: " << s.flag << " image '" << *s.path << "' is " << what
              << "; images are read as 8-bit BGR (grey copied to three channels, 16-bit scaled "
                 "to 8 bits)"
              << std::endl;
    break;
  }
  pipeline::WindowInputOptions opts;
  opts.height = resize_h;
  opts.width = resize_w;
  opts.allow_aspect_change = args.allow_aspect_change;
  return BuildInput(meta, opts, sources, " image", "all four images must have the same size");
}

// A depth map: a .npy of float32 (H, W) in metres, or an image file holding one channel of
// 16-bit integers (depth * --depth-units) or 32-bit floats (metres, e.g. a TIFF).
Result<cv::Mat> ReadDepthMap(const std::string& flag, const std::string& path) {
  if (std::string problem = CheckInputFile(path, flag + " depth map"); !problem.empty()) {
    return Status::Error(problem);
  }
  if (LowerExtension(path) == ".npy") {
    Result<io::NpyArray> array = io::ReadNpy(path);
    if (!array.ok()) return Status::Error(flag + ": " + array.message());
    std::vector<int64_t> shape = array->shape;
    if (shape.size() == 3 && shape[2] == 1) shape.pop_back();
    if (shape.size() != 2 ||
        config::CheckSize(config::kInputSide, "", shape[0], shape[1]).size() > 0) {
      return Status::Error(flag + " depth map '" + path + "': shape " + array->ShapeString() +
                           " is not (H, W) or (H, W, 1) within the input size limits");
    }
    cv::Mat depth(static_cast<int>(shape[0]), static_cast<int>(shape[1]), CV_32FC1);
    std::copy(array->data.begin(), array->data.end(), depth.ptr<float>(0));
    return depth;
  }
  cv::Mat depth;
  if (std::string why = camera::ReadImageFile(path, cv::IMREAD_UNCHANGED, &depth); !why.empty()) {
    return Status::Error(flag + " depth map '" + path + "' " + why);
  }
  if (depth.type() != CV_16UC1 && depth.type() != CV_32FC1) {
    return Status::Error(
        flag + " depth map '" + path + "' decoded to " + std::to_string(depth.channels()) +
        " channel(s) of " +
        (depth.depth() == CV_8U ? "8-bit" : "type " + std::to_string(depth.depth())) +
        " values; a depth map is one channel of 16-bit integers (depth * "
        "--depth-units) or 32-bit floats in metres");
  }
  return depth;
}

// Reads two RGB-D frames (colour images and depth maps) and builds the network input as the
// model's metadata prescribes (camera::RgbdPreprocessor, through pipeline::WindowInput).
Result<InputTensor> InputFromRgbd(const InferArgs& args, const ModelMetadata& meta, int resize_h,
                                  int resize_w) {
  // Colour, depth, colour, depth: the depth maps are the odd entries.
  InputFile sources[4] = {{"--color0", &args.color0, {}},
                          {"--depth0", &args.depth0, {}},
                          {"--color1", &args.color1, {}},
                          {"--depth1", &args.depth1, {}}};
  for (size_t i = 0; i < 4; ++i) {
    InputFile& s = sources[i];
    if (i % 2 == 0) {
      if (Status read = ReadColourImage(s); !read.ok()) return read;
      continue;
    }
    Result<cv::Mat> depth = ReadDepthMap(s.flag, *s.path);
    if (!depth.ok()) return depth.status();
    s.image = *depth;
  }
  pipeline::WindowInputOptions opts;
  opts.height = resize_h;
  opts.width = resize_w;
  opts.depth_units = args.depth_units;
  return BuildInput(meta, opts, sources, "",
                    "both frames' colour and depth must have the same size");
}

// Reads an (H, W, C) or (1, H, W, C) float32 array already in the model's channel order.
Result<InputTensor> InputFromNpy(const std::string& path, const InputDesc& desc) {
  if (std::string problem = CheckInputFile(path, "--input-npy file"); !problem.empty()) {
    return Status::Error(problem);
  }
  Result<io::NpyArray> array = io::ReadNpy(path);
  if (!array.ok()) return array.status();
  std::vector<int64_t> shape = array->shape;
  if (shape.size() == 4 && shape[0] == 1) shape.erase(shape.begin());
  if (shape.size() != 3 || shape[0] <= 0 || shape[1] <= 0 ||
      shape[0] > std::numeric_limits<int>::max() || shape[1] > std::numeric_limits<int>::max()) {
    return Status::Error(path + ": shape " + array->ShapeString() + " is not (H, W, " +
                         std::to_string(desc.channels) + ") or (1, H, W, " +
                         std::to_string(desc.channels) + ")");
  }
  const config::IntRange& sides =
      desc.image_order.empty() ? config::kTensorSide : config::kInputSide;
  if (std::string problem =
          config::CheckSize(sides, path + ": shape " + array->ShapeString(), shape[0], shape[1]);
      !problem.empty()) {
    return Status::Error(problem);
  }
  if (shape[2] != desc.channels) {
    return Status::Error(path + ": shape " + array->ShapeString() + " has " +
                         std::to_string(shape[2]) + " channels but the model takes " +
                         std::to_string(desc.channels));
  }
  if (Status finite = pipeline::CheckFiniteTensor(array->data, static_cast<int>(shape[1]),
                                                  static_cast<int>(shape[2]), path);
      !finite.ok()) {
    return finite;
  }
  InputTensor input;
  input.height = static_cast<int>(shape[0]);
  input.width = static_cast<int>(shape[1]);
  input.data = std::move(array->data);
  input.description = "array " + path;
  return input;
}

struct ChannelStats {
  profiling::RunningStats finite;  // min, max, mean of the finite values
  size_t nan = 0;
  size_t inf = 0;
};

// Whether any RGB-D frame option was given.
bool AnyRgbd(const InferArgs& args) {
  return !args.color0.empty() || !args.depth0.empty() || !args.color1.empty() ||
         !args.depth1.empty();
}

// The checks decided from the command line alone, before any file is read: one input kind, all
// of its options, the depth units, --size, the output's format. A usage error's message, or "".
std::string CheckInferFlags(const InferArgs& args, int* resize_h, int* resize_w) {
  const bool any_image =
      !args.left0.empty() || !args.right0.empty() || !args.left1.empty() || !args.right1.empty();
  const bool any_rgbd = AnyRgbd(args);
  if (int(any_image) + int(any_rgbd) + int(!args.input_npy.empty()) > 1) {
    return "give one input: the four stereo images, the two RGB-D frames or "
           "--input-npy";
  }
  if (any_rgbd) {
    std::string missing;
    if (args.color0.empty()) missing += " --color0";
    if (args.depth0.empty()) missing += " --depth0";
    if (args.color1.empty()) missing += " --color1";
    if (args.depth1.empty()) missing += " --depth1";
    if (!missing.empty()) {
      return "missing RGB-D option(s):" + missing +
             " (all four of --color0 --depth0 --color1 --depth1 are needed)";
    }
  } else if (args.input_npy.empty()) {
    std::string missing;
    if (args.left0.empty()) missing += " --left0";
    if (args.right0.empty()) missing += " --right0";
    if (args.left1.empty()) missing += " --left1";
    if (args.right1.empty()) missing += " --right1";
    if (!missing.empty()) {
      return any_image ? "missing image option(s):" + missing +
                             " (all four of --left0 --right0 --left1 --right1 are "
                             "needed)"
                       : "no input: give --left0 --right0 --left1 --right1, "
                         "--color0 --depth0 --color1 --depth1, or --input-npy";
    }
  }
  if (!(args.depth_units > 0) || !std::isfinite(args.depth_units)) {
    return "--depth-units: must be positive, got " + FormatFloat(args.depth_units);
  }
  if (!args.size.empty()) {
    if (!ParseSize(args.size, resize_h, resize_w)) {
      return "--size: expected HxW with positive integers (e.g. 540x960), got '" + args.size + "'";
    }
    if (!args.input_npy.empty()) {
      return "--size resizes images; it cannot be used with --input-npy";
    }
    if (std::string problem = config::CheckSize(config::kInputSide, "--size", *resize_h, *resize_w);
        !problem.empty()) {
      return problem;
    }
  }
  if (const std::string out_ext = LowerExtension(args.output);
      out_ext != ".pfm" && out_ext != ".npy") {
    return "-o " + args.output + ": unsupported output format '" +
           (out_ext.empty() ? std::string("(no extension)") : out_ext) +
           "' (supported: .pfm, 3-channel PFM; .npy, float32 (H,W,3))";
  }

  return "";
}

// Per output channel: min, max and mean over the finite values; then whether every value is
// finite.
void PrintOutputStats(const std::vector<float>& output, const TensorShape& shape,
                      const ModelMetadata& meta) {
  const size_t channels = static_cast<size_t>(shape.channels);
  std::vector<ChannelStats> stats(channels);
  for (size_t i = 0; i < output.size(); ++i) {
    ChannelStats& s = stats[i % channels];
    const float v = output[i];
    if (std::isnan(v)) {
      ++s.nan;
    } else if (std::isinf(v)) {
      ++s.inf;
    } else {
      s.finite.Add(v);
    }
  }
  std::cout << "output  " << shape.height << "x" << shape.width << "x" << shape.channels
            << " (units: " << UnitsText(meta) << ")\n";
  size_t nan = 0;
  size_t inf = 0;
  for (size_t c = 0; c < channels; ++c) {
    const ChannelStats& s = stats[c];
    std::string name = c < meta.output.channel_names.size() ? meta.output.channel_names[c]
                                                            : "ch" + std::to_string(c);
    char line[160];
    if (s.finite.count() > 0) {
      std::snprintf(line, sizeof(line), "  %-4s  min %12.6g  max %12.6g  mean %12.6g", name.c_str(),
                    s.finite.min(), s.finite.max(), s.finite.mean());
    } else {
      std::snprintf(line, sizeof(line), "  %-4s  no finite values", name.c_str());
    }
    std::cout << line << "\n";
    nan += s.nan;
    inf += s.inf;
  }
  if (nan == 0 && inf == 0) {
    std::cout << "finite  yes (all " << GroupDigits(output.size()) << " values)\n";
  } else {
    std::cout << "finite  NO: " << GroupDigits(nan) << " NaN, " << GroupDigits(inf)
              << " infinite of " << GroupDigits(output.size()) << " values\n";
  }
}

// The flow as .pfm or .npy, as `path` says (checked by CheckInferFlags).
Status WriteFlow(const std::string& path, const std::vector<float>& output,
                 const TensorShape& shape) {
  if (LowerExtension(path) == ".pfm") {
    return io::WritePfm(path, output, shape.height, shape.width, shape.channels);
  }
  const int64_t dims[3] = {shape.height, shape.width, shape.channels};
  return io::WriteNpy(path, dims, output);
}

int RunInfer(const InferArgs& args) {
  int resize_h = 0;
  int resize_w = 0;
  if (std::string usage = CheckInferFlags(args, &resize_h, &resize_w); !usage.empty()) {
    return ReportError(kName, usage, kExitUsage);
  }
  const std::string out_ext = LowerExtension(args.output);
  const bool any_rgbd = AnyRgbd(args);
  if (std::string problem = CheckOutputFile(args.output, "-o"); !problem.empty()) {
    return ReportError(kName, problem, kExitFailure);
  }

  // Model.
  Result<std::shared_ptr<const Model>> loaded = LoadModelFile(args.model);
  if (!loaded.ok()) return ReportError(kName, loaded.message(), kExitFailure);
  std::shared_ptr<const Model> model = std::move(loaded).value();
  const ModelMetadata& meta = model->metadata();
  if (std::string notice = UntrainedNotice(args.model, meta.training); !notice.empty()) {
    std::cout << notice << "\n";
  }

  // Input.
  if (any_rgbd != meta.input.is_rgbd() && args.input_npy.empty()) {
    return ReportError(kName,
                       meta.input.is_rgbd()
                           ? args.model +
                                 " reads two RGB-D frames: give --color0 --depth0 "
                                 "--color1 --depth1 (or --input-npy)"
                           : args.model + " does not read RGB-D frames (its input: " +
                                 (meta.input.is_tensor() ? std::string("a plain tensor")
                                                         : std::string("stereo pairs")) +
                                 "); give --left0 --right0 --left1 --right1 or --input-npy",
                       kExitUsage);
  }
  Result<InputTensor> input = !args.input_npy.empty() ? InputFromNpy(args.input_npy, meta.input)
                              : any_rgbd ? InputFromRgbd(args, meta, resize_h, resize_w)
                                         : InputFromImages(args, meta, resize_h, resize_w);
  if (!input.ok()) return ReportError(kName, input.message(), kExitFailure);
  const int height = input->height;
  const int width = input->width;

  SessionOptions options;
  options.max_height = height;
  options.max_width = width;
  if (Status env = tools::ApplySessionEnvironment(options); !env.ok()) {
    return ReportError(kName, env.message(), kExitUsage);
  }
  if (std::string problem = ForcedIsaPrecisionProblem(*model, options.isa); !problem.empty()) {
    return ReportError(
        kName, args.model + ": " + problem + " (ISA " + IsaName(options.isa) + " from SFRT_ISA)",
        kExitFailure);
  }
  Result<std::unique_ptr<Session>> session = Session::Create(model, options);
  if (!session.ok()) {
    return ReportError(
        kName,
        "cannot create a session for " + SizeString(height, width) + ": " + session.message(),
        kExitFailure);
  }
  if (std::string notice = PrecisionFallbackNotice(*model, (*session)->isa()); !notice.empty()) {
    std::cout << notice << "\n";
  }
  Result<TensorShape> out_shape = (*session)->OutputShape(height, width);
  if (!out_shape.ok()) return ReportError(kName, out_shape.message(), kExitFailure);
  if (out_ext == ".pfm" && out_shape->channels != 3 && out_shape->channels != 1) {
    return ReportError(kName,
                       "the model outputs " + std::to_string(out_shape->channels) +
                           " channels; PFM holds 1 or 3 (write .npy instead)",
                       kExitFailure);
  }
  std::vector<float> output(out_shape->elements());

  std::cout << "model   " << args.model << " (" << meta.name << ")\n"
            << "input   " << SizeString(height, width) << " from " << input->description << "\n";
  const auto start = std::chrono::steady_clock::now();
  Status run = (*session)->Run(input->data, height, width, output);
  const auto stop = std::chrono::steady_clock::now();
  if (!run.ok()) return ReportError(kName, run.message(), kExitFailure);
  const double ms = std::chrono::duration<double, std::milli>(stop - start).count();
  char time_line[64];
  std::snprintf(time_line, sizeof(time_line), "%.1f ms", ms);
  std::cout << "run     " << time_line << " (Session::Run, steady_clock)\n";

  PrintOutputStats(output, *out_shape, meta);
  if (Status written = WriteFlow(args.output, output, *out_shape); !written.ok()) {
    return ReportError(kName, written.message(), kExitFailure);
  }
  std::cout << "wrote   " << args.output << "\n";
  return kExitOk;
}

}  // namespace

Command AddInferCommand(CLI::App& parent) {
  auto args = std::make_shared<InferArgs>();
  CLI::App* cmd =
      parent.add_subcommand("infer", "Run the network on one frame pair and write the scene flow");
  cmd->add_option("--model", args->model, "Model file (.sfrt)")->required();
  cmd->add_option("--left0", args->left0, "Left image at time t");
  cmd->add_option("--right0", args->right0, "Right image at time t");
  cmd->add_option("--left1", args->left1, "Left image at time t+1");
  cmd->add_option("--right1", args->right1, "Right image at time t+1");
  cmd->add_option("--color0", args->color0, "RGB-D models: colour image at time t");
  cmd->add_option("--depth0", args->depth0,
                  "RGB-D models: depth map at time t (16-bit PNG or TIFF in --depth-units, 32-bit "
                  "float TIFF or float32 (H,W) .npy in metres; 0 = no depth)");
  cmd->add_option("--color1", args->color1, "RGB-D models: colour image at time t+1");
  cmd->add_option("--depth1", args->depth1, "RGB-D models: depth map at time t+1");
  cmd->add_option("--depth-units", args->depth_units,
                  "Units per metre of 16-bit depth maps (1000: millimetres, most RGB-D cameras; "
                  "5000: the TUM RGB-D benchmark)")
      ->capture_default_str();
  cmd->add_option("--input-npy", args->input_npy,
                  "Network input as float32 .npy, shape (H,W,C) or (1,H,W,C), C = the model's "
                  "input channels, already ordered and normalised (instead of the images)");
  cmd->add_option("-o,--output", args->output,
                  "Output file: .pfm (3-channel PFM) or .npy (float32, shape (H,W,3))")
      ->required();
  cmd->add_option(
      "--size", args->size,
      "Resize the four images (or RGB-D frames, depth by the nearest sample) to HxW "
      "before inference (not --input-npy; default for images: the size a trained "
      "model records, as sfrt run chooses it, else their own; RGB-D frames: their own)");
  cmd->add_flag("--allow-aspect-change", args->allow_aspect_change,
                "Take a --size of the inverse aspect of the images (refused otherwise, as a "
                "likely WxH given for HxW)");
  cmd->footer(
      "Input: four images of the same size, read with OpenCV (BGR), arranged in the model's\n"
      "image order, converted to RGB if the model says so and normalised as its metadata\n"
      "prescribes; or a float32 .npy already in the model's channel order. The session is\n"
      "planned for exactly the input size. Output: dX, dY, dZ per pixel of left0, in the\n"
      "training camera's units. Prints the input size, the time Session::Run took, the units\n"
      "the model file states (unknown for files before schema 1.2), per-channel min/max/mean\n"
      "of the output and whether every value is finite.\n"
      "A model of two RGB-D frames (sfrt export --input-kind rgbd) reads --color0 --depth0\n"
      "--color1 --depth1 instead: colour as the images above, depth in metres fed as its\n"
      "metadata prescribes, a depth of 0 (or negative, or not finite) as missing.\n"
      "Exit codes: 0 success, 1 runtime or input failure, 2 usage error.");
  return Command{cmd, [args] { return RunInfer(*args); }};
}

}  // namespace sfrt::tools
