#include "replay.h"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "errors.h"
#include "model.h"
#include "sfrt/camera/stereo_source.h"
#include "sfrt/pipeline/log.h"
#include "sfrt/pipeline/pipeline.h"
#include "sfrt/pipeline/sink.h"
#include "sfrt/pipeline/sources.h"
#if SFRT_HAVE_BAGS
#include "bags/any_bag.h"
#endif

namespace py = pybind11;

namespace sfrt::python {
namespace {

// One window as the iterator yields it.
struct PyWindow {
  py::array_t<float> flow;
  int64_t index = 0;
  double t0 = 0;
  double t1 = 0;
  py::dict sources;
  std::string name;
};

// What the output stage hands the Python thread: the window's facts and its flow, copied once
// out of the pipeline's reused buffer into memory the returned array will own.
struct Delivered {
  pipeline::FrameMeta meta;
  std::vector<float>* flow = nullptr;  // owned until handed to numpy
  int height = 0;
  int width = 0;
  int channels = 0;
};

// The pipeline's warnings and notes, kept for Replay.warnings (no console output).
class KeepLog final : public pipeline::LogSink {
 public:
  void Write(pipeline::LogLevel level, std::string_view tag, std::string_view text) override {
    if (level > pipeline::LogLevel::kInfo) return;  // errors, warnings and notes
    std::lock_guard<std::mutex> lock(mu_);
    lines_.push_back(std::string(tag) + ": " + std::string(text));
  }
  void Progress(std::string_view, bool) override {}
  std::vector<std::string> lines() const {
    std::lock_guard<std::mutex> lock(mu_);
    return lines_;
  }

 private:
  mutable std::mutex mu_;
  std::vector<std::string> lines_;
};

class PyReplay;

// The sink between the output stage and the iterator: a queue of two windows; a full queue
// holds the output stage (the replay's queues then hold the rest: nothing is dropped).
class HandOffSink final : public pipeline::FlowSink {
 public:
  explicit HandOffSink(PyReplay* owner) : owner_(owner) {}
  std::string name() const override { return "python"; }
  Status Write(const pipeline::FlowFrame& frame) override;
  Status Finished(const nlohmann::json& summary) override;

 private:
  PyReplay* owner_;
};

class PyReplay {
 public:
  PyReplay(std::shared_ptr<PyModel> model, std::unique_ptr<pipeline::FrameSource> source,
           pipeline::PipelineOptions options)
      : model_(std::move(model)),
        source_(std::move(source)),
        options_(std::move(options)),
        sink_(this) {
    options_.stop = &stop_;
    options_.log = &log_;
    options_.sinks = {&sink_};
    thread_ = std::thread([this] {
      pipeline::PipelineResult result =
          pipeline::RunPipeline(model_->model, source_.get(), options_);
      std::lock_guard<std::mutex> lock(mu_);
      result_ = std::move(result);
      finished_ = true;
      changed_.notify_all();
    });
  }
  ~PyReplay() {
    if (PyGILState_Check()) {
      py::gil_scoped_release released;
      Close();
    } else {
      Close();
    }
  }
  PyReplay(const PyReplay&) = delete;
  PyReplay& operator=(const PyReplay&) = delete;

  PyWindow Next() {
    Delivered item;
    bool have = false;
    {
      py::gil_scoped_release released;
      std::unique_lock<std::mutex> lock(mu_);
      changed_.wait(lock, [this] { return !queue_.empty() || finished_ || closed_; });
      if (!queue_.empty() && !closed_) {
        item = queue_.front();
        queue_.pop_front();
        have = true;
        changed_.notify_all();
      }
    }
    if (!have) Finish();
    return Wrap(item);
  }

  // Stops the replay (the windows not taken are dropped) and waits for its thread.
  void Close() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      closed_ = true;
      for (Delivered& d : queue_) delete d.flow;
      queue_.clear();
      changed_.notify_all();
    }
    stop_.store(true);
    // Once, whichever thread gets here first (a close() beside a next() that reached the end);
    // the others wait until the pipeline's thread has ended.
    std::call_once(joined_, [this] { thread_.join(); });
  }

  void CloseFromPython() {
    py::gil_scoped_release released;
    Close();
  }

  // Called on the output stage's thread.
  Status Deliver(const pipeline::FlowFrame& frame) {
    auto flow = std::make_unique<std::vector<float>>(frame.flow.begin(), frame.flow.end());
    std::unique_lock<std::mutex> lock(mu_);
    changed_.wait(lock, [this] { return queue_.size() < 2 || closed_; });
    if (closed_) return Status::Ok();  // nobody will read it
    queue_.push_back(
        Delivered{*frame.meta, flow.release(), frame.height, frame.width, frame.channels});
    changed_.notify_all();
    return Status::Ok();
  }
  void KeepSummary(const nlohmann::json& summary) {
    std::lock_guard<std::mutex> lock(mu_);
    summary_ = summary.dump();
  }

  py::object Summary() const {
    std::lock_guard<std::mutex> lock(mu_);
    if (summary_.empty()) return py::none();
    return py::module_::import("json").attr("loads")(summary_);
  }
  std::vector<std::string> Warnings() const { return log_.lines(); }

 private:
  // The end of the windows: StopIteration, or the error that ended the run.
  [[noreturn]] void Finish() {
    {
      py::gil_scoped_release released;
      Close();
    }
    if (result_.started && result_.status.ok()) throw py::stop_iteration();
    if (!result_.started && result_.status.ok()) throw py::stop_iteration();  // closed early
    if (result_.usage_error) throw py::value_error(result_.status.message());
    throw Error(result_.status.message());
  }

  static PyWindow Wrap(const Delivered& d) {
    PyWindow w;
    py::capsule owner(d.flow, [](void* p) { delete static_cast<std::vector<float>*>(p); });
    w.flow = py::array_t<float>({d.height, d.width, d.channels}, d.flow->data(), owner);
    w.index = d.meta.window;
    auto seconds = [](int64_t stamp, int64_t capture) {
      return static_cast<double>(stamp != 0 ? stamp : capture) * 1e-9;
    };
    w.t0 = seconds(d.meta.stamp_ns[0], d.meta.capture_ns[0]);
    w.t1 = seconds(d.meta.stamp_ns[1], d.meta.capture_ns[1]);
    w.sources["sequence"] = d.meta.sequence;
    w.sources["frame0"] = d.meta.frame0;
    w.sources["frame1"] = d.meta.frame1;
    w.sources["left0"] = d.meta.left0_path;
    w.name = pipeline::OutputStem(d.meta);
    return w;
  }

  std::shared_ptr<PyModel> model_;
  std::unique_ptr<pipeline::FrameSource> source_;
  pipeline::PipelineOptions options_;
  HandOffSink sink_;
  KeepLog log_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mu_;
  std::condition_variable changed_;
  std::deque<Delivered> queue_;
  bool finished_ = false;
  bool closed_ = false;
  pipeline::PipelineResult result_;
  std::string summary_;
  std::thread thread_;
  std::once_flag joined_;
};

Status HandOffSink::Write(const pipeline::FlowFrame& frame) { return owner_->Deliver(frame); }
Status HandOffSink::Finished(const nlohmann::json& summary) {
  owner_->KeepSummary(summary);
  return Status::Ok();
}

struct ReplayArgs {
  std::string left, right, dataset, video, bag;
  std::string left_topic, right_topic, rendering_pass, on_bad_frame;
};

// The source the arguments name, probed first as `sfrt run` probes it (errors name the path).
std::unique_ptr<pipeline::FrameSource> OpenSource(const ReplayArgs& a) {
  const int given = !a.dataset.empty() + (!a.left.empty() || !a.right.empty()) + !a.video.empty() +
                    !a.bag.empty();
  if (given != 1) {
    throw py::value_error(
        "give exactly one source: left= and right= (folders or globs), "
        "dataset= (a Scene Flow tree), video= (side by side) or bag=");
  }
  Result<camera::BadFramePolicy> on_bad = camera::ParseBadFramePolicy(a.on_bad_frame);
  if (!on_bad.ok()) {
    throw py::value_error("on_bad_frame: expected 'skip' or 'stop', got '" + a.on_bad_frame + "'");
  }
  if (!a.bag.empty()) {
#if SFRT_HAVE_BAGS
    pipeline::BagReplaySpec spec;
    spec.path = a.bag;
    spec.left_topic = a.left_topic;
    spec.right_topic = a.right_topic;
    spec.on_bad_frame = *on_bad;
    std::error_code ec;
    if (!std::filesystem::is_directory(spec.path, ec)) CheckReadablePath(spec.path, "bag", false);
    Result<bags::BagFormat> format = bags::BagFormatOf(spec.path);
    ThrowValueIfError(format.status());
    ThrowValueIfError(format->probe(spec).status());
    return format->make(spec);
#else
    throw Error("this sfrt was built without bag replay (ros2/)");
#endif
  }
  pipeline::ReplaySpec spec;
  if (!a.dataset.empty()) {
    CheckReadablePath(a.dataset, "dataset", true);
    spec.kind = pipeline::ReplaySpec::Kind::kDataset;
    spec.root = a.dataset;
  } else if (!a.video.empty()) {
    CheckReadablePath(a.video, "video", false);
    spec.kind = pipeline::ReplaySpec::Kind::kVideo;
    spec.video = a.video;
  } else {
    if (a.left.empty() || a.right.empty()) throw py::value_error("left= and right= go together");
    spec.kind = pipeline::ReplaySpec::Kind::kPlain;
    spec.left = a.left;
    spec.right = a.right;
  }
  spec.pass = a.rendering_pass;
  spec.on_bad_frame = *on_bad;
  ThrowValueIfError(pipeline::ProbeReplay(spec).status());
  return pipeline::MakeReplaySource(spec);
}

std::unique_ptr<PyReplay> StartReplay(std::shared_ptr<PyModel> model, const ReplayArgs& args,
                                      const py::object& size, int threads, const std::string& isa,
                                      int64_t max_frames) {
  pipeline::PipelineOptions options;
  if (!size.is_none()) SessionSize(*model, size, &options.height, &options.width);
  if (max_frames < 0) throw py::value_error("max_frames: must be 0 (all) or more");
  options.threads = ThreadsArgument(threads);
  options.isa = ParseIsaArgument(isa);
  options.max_frames = max_frames;
  options.write_flow = false;
  options.write_png = false;
  options.write_summary = false;
  options.progress = pipeline::ProgressMode::kOff;
  options.model_path = model->path;
  std::unique_ptr<pipeline::FrameSource> source = OpenSource(args);
  return std::make_unique<PyReplay>(std::move(model), std::move(source), std::move(options));
}

}  // namespace

void BindReplay(py::module_& m) {
  py::class_<PyWindow>(m, "Window", "One (t, t+1) window of a replay and its flow.")
      .def_readonly("flow", &PyWindow::flow,
                    "float32 (h, w, 3): the flow `sfrt run` writes for this window, bit for bit "
                    "(an array of its own)")
      .def_readonly("index", &PyWindow::index, "The window's number in source order (0, 1, ...)")
      .def_readonly("t0", &PyWindow::t0,
                    "Time of pair t in seconds: the bag's header stamp where the source has one, "
                    "else its capture time (CLOCK_MONOTONIC; for files, the end of the read)")
      .def_readonly("t1", &PyWindow::t1, "Time of pair t+1, as t0")
      .def_readonly("sources", &PyWindow::sources,
                    "dict: sequence, frame0, frame1 (the frame numbers of pair t and t+1) and "
                    "left0 (the left image's path at t; empty for bags and videos)")
      .def_readonly("name", &PyWindow::name,
                    "The stem of the files `sfrt run` writes for this window, e.g. "
                    "'0000_000003'")
      .def("__repr__", [](const PyWindow& w) {
        return "<sfrt.Window " + std::to_string(w.index) + " '" + w.name + "' flow " +
               std::to_string(w.flow.shape(0)) + "x" + std::to_string(w.flow.shape(1)) + ">";
      });

  py::class_<PyReplay>(m, "Replay", R"doc(
The windows of a replay, from sfrt.replay(): iterate it (or use it in a `with` block, which
closes it). The pipeline runs on its own threads while Python takes the windows; it waits for a
slow reader and drops nothing. close() stops it early.
)doc")
      .def("__iter__", [](PyReplay& r) -> PyReplay& { return r; })
      .def("__next__", &PyReplay::Next)
      .def("close", &PyReplay::CloseFromPython, "Stops the replay; later windows are not made.")
      .def("__enter__", [](PyReplay& r) -> PyReplay& { return r; })
      .def("__exit__", [](PyReplay& r, py::args) { r.CloseFromPython(); })
      .def_property_readonly("summary", &PyReplay::Summary,
                             "The run's summary (what summary.json holds for `sfrt run`) once "
                             "the windows are exhausted; None before")
      .def_property_readonly("warnings", &PyReplay::Warnings,
                             "The pipeline's warnings and notes so far");

  m.def(
      "replay",
      [](std::shared_ptr<PyModel> model, const std::string& left, const std::string& right,
         const std::string& dataset, const std::string& video, const std::string& bag,
         const std::string& left_topic, const std::string& right_topic, const py::object& size,
         int threads, const std::string& isa, int64_t max_frames, const std::string& rendering_pass,
         const std::string& on_bad_frame) {
        ReplayArgs args{left,       right,       dataset,        video,       bag,
                        left_topic, right_topic, rendering_pass, on_bad_frame};
        return StartReplay(std::move(model), args, size, threads, isa, max_frames);
      },
      py::arg("model").none(false), py::kw_only(), py::arg("left") = "", py::arg("right") = "",
      py::arg("dataset") = "", py::arg("video") = "", py::arg("bag") = "",
      py::arg("left_topic") = "left/image_rect", py::arg("right_topic") = "right/image_rect",
      py::arg("size") = py::none(), py::arg("threads") = 1, py::arg("isa") = "auto",
      py::arg("max_frames") = 0, py::arg("rendering_pass") = "clean",
      py::arg("on_bad_frame") = "stop", R"doc(
Replays recorded stereo through the pipeline, as `sfrt run` does, yielding each window's flow.

    for w in sfrt.replay(m, left="dir/left", right="dir/right", size=(96, 128)):
        w.flow, w.index, w.t0, w.t1, w.sources, w.name

Sources (exactly one): left= and right= (folders or globs of images, paired by sorted order),
dataset= (a Scene Flow tree such as `sfrt synth` writes), video= (side-by-side stereo), or bag=
(a ROS 1 .bag, or a rosbag2 folder, .mcap or .db3) with left_topic= and right_topic=.
size: (H, W), or None for what `sfrt run` chooses (the size a trained model records, else the
frames'). threads, isa: as Session. max_frames: stop after this many (0: all).
rendering_pass: "clean" or "final" (Scene Flow datasets). on_bad_frame: "stop" (an error) or
"skip".
The windows, their order and their flow are those `sfrt run --flow-format npy` writes for the
same source and options, bit for bit. The run's errors are raised from the iteration
(sfrt.Error; ValueError for a size the frames cannot take); a missing path raises
FileNotFoundError here.
)doc");
}

}  // namespace sfrt::python
