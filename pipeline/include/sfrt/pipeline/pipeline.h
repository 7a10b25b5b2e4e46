// The real-time scene-flow pipeline behind `sfrt run` (issue #5).
//
// Four stages, each on its own thread, connected by bounded LatestQueues (latest_queue.h):
//
//   source ──q1──> preprocess ──q2──> infer ──q3──> output
//   (camera or     (rectify/resize,    (Session::Run  (flow .pfm/.npy, visualisation PNG,
//    replay: one    the model's         into a        optional AVI, statistics, progress)
//    (t, t+1)       normalisation)      preallocated
//    window)                            output)
//
// Every window carries the capture timestamps of its two stereo pairs and the start and end of
// each stage, all on one clock: CLOCK_MONOTONIC (std::chrono::steady_clock on Linux, the clock
// V4L2 stamps buffers with). For files the capture time is when the source finished reading.
// End-to-end latency = end of output - capture of pair t+1; a window over --budget-ms is a
// deadline miss.
//
// Queue policy: kNewestWins (live cameras) discards the older queued window when a newer one
// arrives, so no stage ever works on a stale frame; the discards are counted per stage. kBlock
// (replays) makes the source wait, so every window is processed.
//
// Memory: every buffer (raw images, network input, flow, visualisation) is allocated before the
// first frame (the queue slots before the threads start, each stage's working buffers as its
// thread starts), at the source's frame size and the model input size, and circulates between
// the stages by swapping. The infer stage only swaps and calls Session::Run: no allocation
// (pipeline_allocation_test). The preprocess stage's resizes (OpenCV's cv::resize, when
// the frame size is not the model's, and at the fallback size) allocate scratch tables on
// each call; its images are not reallocated.
//
// Stopping: `stop` (set from a signal handler by the caller) makes the source stop reading;
// windows already read are finished and written (at most one per queue slot and stage), so
// every output file is complete (all are written to a temporary name and renamed). A fatal error
// in a stage stops the source and discards the queued windows. The summary says how far the run
// got and why it stopped; it goes to every sink's Finished() in every case (sink.h), and to
// summary.json in the output directory through a SummaryFileSink unless write_summary is false.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sfrt/camera/calibration.h"
#include "sfrt/camera/preprocess.h"
#include "sfrt/camera/stereo_source.h"
#include "sfrt/camera/window_chain.h"
#include "sfrt/config/vocabulary.h"
#include "sfrt/isa.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/latest_queue.h"
#include "sfrt/pipeline/stats.h"
#include "sfrt/pipeline/visualize.h"
#include "sfrt/session.h"
#include "sfrt/status.h"
#include "sfrt/vocabulary/failure_policy.h"

namespace sfrt::pipeline {

class FrameProfiler;  // profiler.h
class FlowSink;       // sink.h
class LogSink;        // log.h

// The model's input metadata as camera/ preprocessing parameters (image order, colour order,
// scale, mean, std). Errors name the metadata field and value.
Result<camera::PreprocessParams> PreprocessFromMetadata(const InputDesc& input);

// What is known about a window before preprocessing.
struct FrameMeta {
  int64_t window = -1;   // number of the window in source order (0, 1, ...)
  std::string sequence;  // "" for single-sequence sources
  int64_t frame0 = -1;   // frame number of pair t (file number, or the camera's sequence)
  int64_t frame1 = -1;   // frame number of pair t+1
  // Set by the source when pair t holds the same images as pair t+1 of the window it delivered
  // just before (window - 1): the preprocess stage then rectifies only pair t+1 and reuses the
  // previous window's (each pair rectified once), when it saw that window.
  bool continues = false;
  std::string left0_path;          // where the left image at t came from ("" for cameras)
  int64_t capture_ns[2] = {0, 0};  // capture time of pair t and t+1 (CLOCK_MONOTONIC)
  // The sensor's own stamps of pair t and t+1 where the source has them (a bag's header stamps
  // of the left images, ns since the epoch); 0 otherwise.
  int64_t stamp_ns[2] = {0, 0};
  // [stage][0 start, 1 end], CLOCK_MONOTONIC ns, indexed by config::Stage (source, preprocess,
  // infer, output), or through start_ns(stage) and end_ns(stage).
  int64_t stage_ns[config::kStageCount][2] = {};
  int64_t& start_ns(config::Stage s) { return stage_ns[config::StageIndex(s)][0]; }
  int64_t& end_ns(config::Stage s) { return stage_ns[config::StageIndex(s)][1]; }
  int64_t start_ns(config::Stage s) const { return stage_ns[config::StageIndex(s)][0]; }
  int64_t end_ns(config::Stage s) const { return stage_ns[config::StageIndex(s)][1]; }
  // Live sources, for pair t+1 (0 for files): when the frame with the later capture time was
  // dequeued, when the pair formed (its partner dequeued too) and when both were converted to BGR.
  // With capture_ns[1] and stage_ns they split the end-to-end latency (LatencyPart).
  int64_t dequeue_ns = 0;
  int64_t paired_ns = 0;
  int64_t converted_ns = 0;
  // The network input size the window was preprocessed and inferred at (set by the preprocess
  // stage): the model input size, or the fallback size under `smaller_input_on_miss`.
  int input_height = 0;
  int input_width = 0;
};

// A (t, t+1) window as read: four BGR images of the source's frame size.
struct WindowItem {
  FrameMeta meta;
  cv::Mat left0, right0, left1, right1;
};

enum class Fetch { kWindow, kEnd };

// The end-to-end latency of a window (end of the output stage - capture of pair t+1) in
// consecutive parts on one clock; they add up to it exactly. For files the capture time is the
// end of the read, so the first three parts are 0.
enum class LatencyPart {
  kCaptureToDequeue,  // the driver's capture timestamp to this process's dequeue
  kStereoPartner,     // dequeued, waiting for the partner frame to be dequeued and matched
  kConvert,           // both frames converted to BGR
  kSourceHandoff,     // the window assembled and handed to the queue
  kQueuePreprocess,   // waiting in the queue before preprocess
  kPreprocess,
  kQueueInfer,
  kInfer,
  kQueueOutput,
  kOutput,
};
inline constexpr int kLatencyParts = 10;
// "capture_to_dequeue", "stereo_partner", "convert", "source_handoff", "queue_preprocess",
// "preprocess", "queue_infer", "infer", "queue_output", "output".
const char* LatencyPartName(LatencyPart part);
// The parts of `meta` (all stages done) in milliseconds, in LatencyPart order.
void SplitLatency(const FrameMeta& meta, double out_ms[kLatencyParts]);

// A source of (t, t+1) windows, driven by the source stage's thread.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Opens the source and returns the frame size of the raw images (width x height). Called once,
  // on the caller's thread, before the stages start.
  virtual Result<cv::Size> Open() = 0;
  // Fills item->meta (sequence, frame numbers, path, capture times) and the four images (reusing
  // their memory when the size matches). Must return within about a second when `stop` is set.
  // An error ends the run (a bad frame under --on-bad-frame stop, a lost device that cannot be
  // reopened, ...).
  virtual Result<Fetch> Next(WindowItem* item, const std::atomic<bool>& stop) = 0;
  // One line, e.g. "replay: Scene Flow dataset ... (2 sequences)".
  virtual std::string Describe() const = 0;
  virtual std::string kind() const = 0;  // "camera", "sbs-camera", "replay", ...
  // Windows the source will deliver, when known up front (replays).
  virtual std::optional<int64_t> total_windows() const { return std::nullopt; }
  // Live sources default to kNewestWins, files to kBlock.
  virtual bool live() const = 0;
  // Source-specific facts for summary.json (camera formats and counters, bad frames).
  virtual void ToJson(nlohmann::json* out) const = 0;
  // Frames the source itself lost before the pipeline saw them (driver sequence gaps, frames
  // left without a stereo partner), for the summary's per-stage drop counts.
  virtual uint64_t drops() const { return 0; }
  // Bad frames skipped (or the one that stopped the run), by path (camera::BadFrame's words).
  using BadFrame = camera::BadFrame;
  virtual std::vector<BadFrame> bad_frames() const { return {}; }
  // How the source chained its pairs into windows (sfrt/camera/window_chain.h, the one rule for
  // every source): windows formed, and pairs that opened none because a frame was lost, the
  // stamps jumped a gap or went backwards. For summary.json's "windows" and the console.
  virtual camera::ChainCounts chain_counts() const { return {}; }

  // Where the source's warnings and events go (log.h); RunPipeline sets its own log before
  // Open(). Null: DefaultLog().
  void set_log(LogSink* log) { log_ = log; }

 protected:
  LogSink& log() const;

 private:
  LogSink* log_ = nullptr;
};

using config::FlowFormat;  // sfrt/config/vocabulary.h: "pfm", "npy"
// What a failed output write (disk full, read-only or vanished directory, ...) does to the run.
// Either way the window's files are all or nothing: every file is written to a temporary name and
// renamed, and the files of a window already written are removed when a later one fails.
//   kStop: the run ends with the error (exit 1), queued windows are discarded.
//   kSkip: the window is dropped, counted and listed in the summary; the run goes on.
using OutputErrorPolicy = vocabulary::FailurePolicy;  // kStop, kSkip
enum class ProgressMode { kAuto, kTty, kLines, kOff };

struct PipelineOptions {
  std::string out_dir;  // must exist
  FlowFormat flow_format = FlowFormat::kPfm;
  bool write_flow = true;
  bool write_png = true;
  OutputErrorPolicy on_output_error = OutputErrorPolicy::kStop;
  std::string video_path;  // "" = no video; written as MJPG AVI
  VisScale vis_scale;      // colour scale of the PNGs and the video (visualize.h)
  double video_fps = 10;
  double budget_ms = 0;    // 0 = no deadline accounting
  int64_t max_frames = 0;  // 0 = until the source ends or a stop
  // > 0: the source reads at most this many windows a second, on a fixed schedule (never in a
  // burst to catch up), as a camera would deliver them; 0 = as fast as the pipeline takes them.
  double source_fps = 0;
  int height = 0;  // model input size; 0 = the size a trained model records, else the source's
  int width = 0;   // (ChooseInputSize)
  // A height x width of the inverse aspect of the source's frames (beyond kAspectTolerance) is
  // refused as a likely WxH given for HxW, unless this says it is meant.
  bool allow_aspect_change = false;
  Isa isa = Isa::kAuto;
  int threads = 1;
  KernelTuning tuning{};  // the session's optimised-path switches (defaults: the fastest)
  // An int8 model whose input only int8 convolutions read (Session::InputQuantization): the
  // preprocess stage writes the network's uint8 input straight from the camera's pixels
  // (camera::Preprocessor::RunQuantized) and the infer stage runs it (Session::RunQuantized):
  // no float32 input, no quantise step, the same flow bit for bit. false: the float32 input.
  bool quantized_input = true;
  std::optional<QueuePolicy> policy;  // default: kNewestWins for live sources, kBlock otherwise
  size_t queue_capacity = 1;
  std::optional<camera::StereoCalibration> calibration;  // rectify with it (else resize only)
  ProgressMode progress = ProgressMode::kAuto;
  int progress_every = 10;  // kLines: one line every this many frames
  std::string model_path;   // for the summary
  // "" = none; else a CSV file, one line per written window: window number, the four stage
  // durations and end to end (ms). For soak runs (tools/soak.sh); --profile has more.
  std::string latency_log;
  // Set asynchronously (signal handler) to stop; stop_signal says which signal (0 = none).
  const std::atomic<bool>* stop = nullptr;
  const std::atomic<int>* stop_signal = nullptr;
  // Deployment settings (`sfrt run --config`, issue #6):
  // called first on each stage's thread with its index (0 source, 1 preprocess, 2 infer,
  // 3 output), e.g. to set the thread's CPU affinity and SCHED_FIFO priority.
  std::function<void(int stage)> on_stage_start;
  bool prefault = false;  // one inference on zeros at setup: arena and weights paged in
  // What a deadline miss does (latency.on_miss): kCountOnly counts it; kDropNext makes the
  // source skip its next window; kSmallerInput runs the next windows at smaller_input_on_miss.
  config::MissAction on_miss = config::MissAction::kCountOnly;
  // on_miss kSmallerInput: after a window over budget the following windows are preprocessed
  // and inferred at this size (<= the model input size in both dimensions, smaller in one;
  // another size is an error at setup); after `recover_after` consecutive in-budget windows at
  // this size the run returns to the model input size. A miss at the fallback size restarts
  // the count (hysteresis). Buffers are sized for the model input size at start, so switching
  // reallocates no buffer and the infer stage allocates nothing (the preprocess stage's resizes
  // allocate their scratch, as at any size other than the frame's). Flow files have the size
  // the window ran at; the PNG/video show the flow upscaled (bilinear) to the model input size,
  // so they keep one size.
  struct Size2 {
    int height = 0;
    int width = 0;
  };
  Size2 smaller_input_on_miss;
  int recover_after = 30;  // >= 1
  // A SummaryFileSink (output_sinks.h) after the caller's sinks; false: no summary.json
  // (outputs.summary: false), the caller's sinks still get the summary.
  bool write_summary = true;
  // Also put every latency sample behind the summary's percentiles in it ("latency_samples_ms":
  // {"stages": {stage: [...]}, "end_to_end", "parts": {part: [...]}, "pictures"}, the latest
  // LatestValues::kDefaultCapacity of each), so the summaries of runs over disjoint parts of one
  // replay merge into the percentiles of all their windows exactly (sfrt run --shard, sfrt merge).
  bool summary_samples = false;
  // Called with the summary's document before the sinks and summary.json get it, to add the
  // caller's members (sfrt run --shard: the shard, its work list and provenance).
  std::function<void(nlohmann::json* summary)> annotate_summary;
  // The visualisation encoders (PNG, video) on a thread of their own behind a queue of this many
  // windows (queued_sink.h: the end to end ends before them; their time is measured apart, and
  // for a live or paced source (source_fps > 0) a picture that cannot keep up is dropped and
  // counted, so it never holds back the flow; otherwise the queue blocks), or 0: on the output
  // stage, all or nothing with the window's flow file. Default: 2 for live and paced sources, 0
  // for unpaced replays (a throughput job that keeps every picture).
  std::optional<size_t> picture_queue;
  // `miss_verdict` (a test seam, null in the product) decides whether a written window counts
  // as a deadline miss, given the budget's verdict (end to end > budget_ms), so a test need not
  // depend on wall-clock speed. `after_window` is called by the output stage once it is done
  // with a written window (after the on-miss state has changed), e.g. to pace a fake source in
  // a test, or for a shard's status file (sfrt run --shard).
  std::function<bool(const FrameMeta& meta, bool over_budget)> miss_verdict;
  std::function<void(const FrameMeta& meta)> after_window;
  // `--profile` (profiler.h): per-frame stage and step timestamps into this preallocated ring.
  FrameProfiler* profiler = nullptr;
  // Called for every window after the outputs above (made as the sinks of output_sinks.h), in
  // this order (sink.h: the callback sink hands a robot program each flow frame in-process). Not
  // owned; each must outlive RunPipeline().
  std::vector<FlowSink*> sinks;
  // Where the library's warnings, notes and progress lines go (log.h), also the source's; not
  // owned. Null: DefaultLog() (stderr, prefix "sfrt pipeline").
  LogSink* log = nullptr;
};

struct PipelineResult {
  Status status;              // ok, or the error that ended the run
  bool started = false;       // false: setup failed (source open, session), no stage ran
  bool usage_error = false;   // setup refused an option against the source (a tool's exit 2)
  int64_t frames = 0;         // windows whose outputs were written
  int64_t output_errors = 0;  // windows whose outputs could not be written (skipped or the stop)
  std::string stopped_by;     // "end of source", "max-frames", "SIGINT", "SIGTERM", "error"
  std::string summary_path;   // "" if even the summary could not be written
  double fps = 0;             // frames / wall time
  // Milliseconds. A latency only when `paced` (a live source, or source_fps > 0); an unpaced
  // replay's windows wait in the queues, so its end to end measures throughput instead.
  profiling::Summary end_to_end;
  bool paced = false;
  profiling::Summary stage[config::kStageCount];  // indexed by config::Stage
  profiling::Summary parts[kLatencyParts];        // the end to end split (LatencyPart order)
  int64_t misses = 0;                             // windows over the budget (or miss_verdict)
  bool pictures_queued = false;                   // PipelineOptions::picture_queue > 0 and pictures
  profiling::Summary pictures_ms;                 // then: the encoders' time per window
  uint64_t pictures_dropped = 0;                  // and the pictures dropped to keep up
  camera::ChainCounts chain;                      // FrameSource::chain_counts() at the end
  int64_t frames_at_fallback_size = 0;  // written windows that ran at smaller_input_on_miss
  int64_t fallback_entries = 0;         // switches from the model input size to the fallback
  std::vector<std::string> warnings;
};

// Runs the pipeline until the source ends, max_frames are written, *stop is set or a stage
// fails. Hands the summary to the sinks' Finished() in every case, and writes summary.json
// (unless the output directory is unusable or write_summary is false).
PipelineResult RunPipeline(std::shared_ptr<const Model> model, FrameSource* source,
                           const PipelineOptions& options);

// Where --video will be written: `path` after following symbolic links (the file renamed onto
// at the end). The MJPG/AVI writer seeks back to finish the file, so it needs a regular file or
// a new path; a character device or FIFO is refused with a message saying so, naming the path.
Result<std::string> ResolveVideoPath(const std::string& path);

// The network input size of a run, and why, as RunPipeline chooses it once the source's frame
// size is known: PipelineOptions::height x width when set; else the size the model records
// (InputDesc::traced_height x traced_width: the size it was traced and trained at, which its
// training camera's focal length is for) when the model is marked trained (an untrained one or
// one of unknown origin has no training size to match); else the frames' size. An asked size whose
// aspect is the inverse of the frames' (within kAspectTolerance) is an error suggesting the swap
// unless allow_aspect_change; any other aspect change is taken with a note (aspect_note).
inline constexpr double kAspectTolerance = 0.10;
struct InputSizeChoice {
  int height = 0;
  int width = 0;
  std::string reason;  // "as asked", "the size the trained model records ...", "the frames' ..."
  std::string aspect_note;  // "" or a warning that the frames are stretched
};
Result<InputSizeChoice> ChooseInputSize(const PipelineOptions& options, const ModelMetadata& model,
                                        int source_height, int source_width);

// {"p50", "p90", "p99", "max", "count"}: a series as summary.json's latencies give it.
nlohmann::json PercentilesJson(const profiling::Summary& summary);

// Output file stem of a window: "<sequence with '/' as '_'>_<frame0, 6 digits>", or
// "frame_<frame0>" when the sequence is empty.
std::string OutputStem(const FrameMeta& meta);

}  // namespace sfrt::pipeline
