#include "sfrt/pipeline/output_sinks.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "png_encoder.h"
#include "sfrt/pipeline/io/atomic_write.h"
#include "sfrt/pipeline/io/npy.h"
#include "sfrt/pipeline/io/pfm.h"

namespace sfrt::pipeline {
namespace {

// The file for `meta`'s window in `dir`: <stem>.<extension>.
std::string PathIn(const std::string& dir, const FrameMeta& meta, const char* extension) {
  return (std::filesystem::path(dir) / (OutputStem(meta) + "." + extension)).string();
}

double Ms(int64_t ns) { return static_cast<double>(ns) / 1e6; }

double StageMs(const FrameMeta& m, config::Stage s) { return Ms(m.end_ns(s) - m.start_ns(s)); }

// Retract() of a file sink: removes the file it wrote last, if any.
void RemoveLastFile(std::string* path) {
  if (!path->empty()) ::unlink(path->c_str());
  path->clear();
}

// Whether the AVI at `path` holds `frames` frames, by its index (nothing is decoded).
Status CheckVideoComplete(const std::string& path, int64_t frames) {
  cv::VideoCapture cap(path, cv::CAP_OPENCV_MJPEG);
  const double indexed = cap.isOpened() ? cap.get(cv::CAP_PROP_FRAME_COUNT) : -1;
  if (indexed == static_cast<double>(frames)) return Status::Ok();
  const std::string found =
      indexed < 0 ? "cannot be read back"
                  : "holds " + std::to_string(static_cast<int64_t>(indexed)) + " frames";
  return Status::Error("'" + path + "' " + found + " though " + std::to_string(frames) +
                       " were written (a failed write, such as a full disk; OpenCV's "
                       "VideoWriter does not report those)");
}

// A CSV field: quoted (with quotes doubled) when it holds a comma, a quote or a line break.
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

// The CSV files streamed as the run goes (latency log, window index), `what` naming them in
// errors: opened with their header line, a line per window, flushed and closed at the end.
Status OpenCsv(const std::string& path, std::string_view header, const char* what,
               io::StreamedFile* file) {
  Result<io::StreamedFile> opened = io::StreamedFile::Open(path);
  if (!opened.ok()) return Status::Error(std::string(what) + ": " + opened.message());
  *file = std::move(opened).value();
  if (Status s = file->Write(header); !s.ok()) {
    return Status::Error(std::string(what) + ": " + s.message());
  }
  return Status::Ok();
}

Status WriteCsvLine(io::StreamedFile* file, std::string_view line, const char* what) {
  if (Status s = file->Write(line); !s.ok()) {
    (void)file->Close();  // a partial line would make the rest unreadable: no more lines
    return Status::Error(std::string(what) + ": " + s.message());
  }
  return Status::Ok();
}

Status CloseCsv(io::StreamedFile* file, const char* what) {
  if (!file->is_open()) return Status::Ok();
  if (Status s = file->Close(); !s.ok())
    return Status::Error(std::string(what) + ": " + s.message());
  return Status::Ok();
}

}  // namespace

// ---------------------------------------------------------------------------------- flow files

FlowFileSink::FlowFileSink(std::string dir, config::FlowFormat format)
    : dir_(std::move(dir)), format_(format) {}

Status FlowFileSink::Write(const FlowFrame& frame) {
  last_path_.clear();
  const bool pfm = format_ == config::FlowFormat::kPfm;
  std::string path = PathIn(dir_, *frame.meta, config::FlowFormatName(format_));
  const int64_t shape[3] = {frame.height, frame.width, frame.channels};
  Result<std::vector<uint8_t>> bytes =
      pfm ? io::SerializePfm(frame.flow, frame.height, frame.width, frame.channels)
          : io::SerializeNpy(shape, frame.flow);
  if (!bytes.ok()) return Status::Error(path + ": " + bytes.message());
  // A file a frame: flushed to disk once, at Stop(), not one fsync a frame (atomic_write.h).
  if (Status s = io::WriteFileAtomically(path, *bytes, io::Flush::kLater); !s.ok()) return s;
  wrote_ = true;
  last_path_ = std::move(path);
  return Status::Ok();
}

void FlowFileSink::Retract() { RemoveLastFile(&last_path_); }

Status FlowFileSink::Stop() { return wrote_ ? io::FlushFileSystemOf(dir_) : Status::Ok(); }

// ------------------------------------------------------------------------------------ renderer

const cv::Mat& FlowRenderer::Render(const FlowFrame& frame) {
  const FrameMeta& m = *frame.meta;
  if (m.window == window_ && m.capture_ns[1] == capture_ns_ && !canvas_.empty()) return canvas_;
  const cv::Mat& left = *frame.left_image;
  std::string label = OutputStem(m);
  const float* flow = frame.flow.data();
  if (frame.height != left.rows || frame.width != left.cols) {
    upscaled_.resize(left.total() * static_cast<size_t>(frame.channels));
    const cv::Mat small(frame.height, frame.width, CV_32FC(frame.channels),
                        const_cast<float*>(frame.flow.data()));
    cv::Mat big(left.rows, left.cols, CV_32FC(frame.channels), upscaled_.data());
    cv::resize(small, big, big.size(), 0, 0, cv::INTER_LINEAR);
    flow = upscaled_.data();
    label += " (" + std::to_string(frame.height) + "x" + std::to_string(frame.width) + ")";
  }
  vis_.Render(left, flow, frame.channels, label, &canvas_);
  window_ = m.window;
  capture_ns_ = m.capture_ns[1];
  return canvas_;
}

// ----------------------------------------------------------------------------------------- PNG

PngSink::PngSink(std::string dir, FlowRenderer* renderer)
    : dir_(std::move(dir)), renderer_(renderer), encoder_(std::make_unique<PngEncoder>()) {}

PngSink::~PngSink() = default;

Status PngSink::Write(const FlowFrame& frame) {
  last_path_.clear();
  const cv::Mat& canvas = renderer_->Render(frame);
  if (Status encoded = encoder_->Encode(canvas, &png_); !encoded.ok()) {
    return Status::Error("cannot encode the visualisation of " + OutputStem(*frame.meta) +
                         " as PNG: " + encoded.message());
  }
  std::string path = PathIn(dir_, *frame.meta, "png");
  if (Status s = io::WriteFileAtomically(path, png_, io::Flush::kLater); !s.ok()) return s;
  wrote_ = true;
  last_path_ = std::move(path);
  return Status::Ok();
}

void PngSink::Retract() { RemoveLastFile(&last_path_); }

Status PngSink::Stop() { return wrote_ ? io::FlushFileSystemOf(dir_) : Status::Ok(); }

// --------------------------------------------------------------------------------------- video

Status VideoSink::Start() {
  // The AVI writer seeks back to finish the file, so only a regular file (or a new path) will
  // do; a symbolic link is followed and the file it names is replaced (atomic_write.h).
  Result<std::string> resolved = ResolveVideoPath(path_);
  if (!resolved.ok()) return resolved.status();
  final_ = std::move(resolved).value();
  tmp_ = final_ + ".tmp.avi";
  return Status::Ok();
}

Status VideoSink::Write(const FlowFrame& frame) {
  const cv::Mat& canvas = renderer_->Render(frame);
  if (!writer_.isOpened()) {
    writer_.open(tmp_, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps_, canvas.size());
    if (!writer_.isOpened()) {
      return Status::Error("cannot open '" + tmp_ +
                           "' for writing with OpenCV VideoWriter (MJPG/AVI)");
    }
  }
  writer_.write(canvas);
  ++frames_;
  return Status::Ok();
}

Status VideoSink::Stop() {
  if (!writer_.isOpened()) return Status::Ok();  // no frame: nothing is replaced
  writer_.release();
  // VideoWriter reports no failed write (a full disk truncates the file silently): read the
  // finished file's index back before it replaces anything.
  if (Status complete = CheckVideoComplete(tmp_, frames_); !complete.ok()) {
    ::unlink(tmp_.c_str());
    return Status::Error("the video '" + path_ +
                         "' was not written (nothing replaced it): " + complete.message());
  }
  std::error_code ec;
  std::filesystem::rename(tmp_, final_, ec);
  if (ec) return Status::Error("cannot rename '" + tmp_ + "' to '" + final_ + "': " + ec.message());
  written_ = true;
  return Status::Ok();
}

// --------------------------------------------------------------------------------- latency log

Status LatencyLogSink::Start() {
  std::string header = "window";
  for (const char* stage : config::kStageNames) header += std::string(",") + stage + "_ms";
  header += ",end_to_end_ms,input_height,input_width,done_monotonic_ms\n";
  return OpenCsv(path_, header, "the latency log", &file_);
}

Status LatencyLogSink::Completed(const WindowRecord& record) {
  const FrameMeta& m = *record.meta;
  char line[256];
  const int n =
      std::snprintf(line, sizeof(line), "%lld,%.4f,%.4f,%.4f,%.4f,%.4f,%d,%d,%.3f\n",
                    static_cast<long long>(m.window), StageMs(m, config::Stage::kSource),
                    StageMs(m, config::Stage::kPreprocess), StageMs(m, config::Stage::kInfer),
                    StageMs(m, config::Stage::kOutput), record.end_to_end_ms, m.input_height,
                    m.input_width, Ms(m.end_ns(config::Stage::kOutput)));
  return WriteCsvLine(
      &file_, std::string_view(line, static_cast<size_t>(std::clamp(n, 0, int{sizeof(line)} - 1))),
      "the latency log");
}

Status LatencyLogSink::Stop() { return CloseCsv(&file_, "the latency log"); }

// ------------------------------------------------------------------------------- window index

WindowIndexSink::WindowIndexSink(std::string dir)
    : path_((std::filesystem::path(dir) / "windows.csv").string()) {}

// Opened at the first window, so a run that writes none leaves no index behind.
Status WindowIndexSink::Open() {
  return OpenCsv(path_, "file,sequence,frame_t,frame_t1,stamp_t_ns,stamp_t1_ns,source_t\n",
                 "the window index", &file_);
}

Status WindowIndexSink::Completed(const WindowRecord& record) {
  if (!opened_) {
    opened_ = true;
    if (Status s = Open(); !s.ok()) return s;
  }
  const FrameMeta& m = *record.meta;
  const std::string line = CsvField(OutputStem(m)) + "," + CsvField(m.sequence) + "," +
                           std::to_string(m.frame0) + "," + std::to_string(m.frame1) + "," +
                           std::to_string(m.stamp_ns[0]) + "," + std::to_string(m.stamp_ns[1]) +
                           "," + CsvField(m.left0_path) + "\n";
  return WriteCsvLine(&file_, line, "the window index");
}

Status WindowIndexSink::Stop() { return CloseCsv(&file_, "the window index"); }

// ------------------------------------------------------------------------------------- summary

SummaryFileSink::SummaryFileSink(std::string dir)
    : path_((std::filesystem::path(dir) / "summary.json").string()) {}

Status SummaryFileSink::Finished(const nlohmann::json& summary) {
  const std::string text = summary.dump(2) + "\n";
  Status s = io::WriteFileAtomically(
      path_, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
  written_ = s.ok();
  return s;
}

}  // namespace sfrt::pipeline
