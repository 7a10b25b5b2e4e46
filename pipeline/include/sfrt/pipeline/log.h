// Where the pipeline library's messages go. The library writes nothing to stderr by itself:
// its warnings (a skipped window, a skipped bad frame, a camera lost or back), notes and progress
// lines all go to a LogSink: PipelineOptions::log, which RunPipeline also hands to its source
// (FrameSource::set_log). A robot program routes them to its own logger (ROS_WARN, syslog, ...);
// `sfrt run` uses a StderrLog with the prefix "sfrt run".
//
// Threads: the stages call Write() from their own threads, so a sink used by a pipeline must take
// calls from several threads at once (StderrLog writes each message with one fprintf, which the
// C library serialises).
#pragma once

#include <string>
#include <string_view>

#include "sfrt/config/vocabulary.h"

namespace sfrt::pipeline {

using config::LogLevel;  // error, warn, info, debug (vocabulary.h)

class LogSink {
 public:
  virtual ~LogSink() = default;
  // One message, without a trailing newline. `tag` is the word a reader sees first: "warning",
  // "note", "camera" (a camera's events: lost, timed out, reconnected).
  virtual void Write(LogLevel level, std::string_view tag, std::string_view text) = 0;
  // A progress line ("12/40 frames, 9.8 fps, p50 102.3 ms end to end"); `final`: the run's last.
  // By default an info message tagged "progress".
  virtual void Progress(std::string_view line, bool /*final*/) {
    Write(LogLevel::kInfo, "progress", line);
  }
  // True when Progress() replaces the previous line in place (a terminal): ProgressMode::kAuto
  // then shows one updating line, else a line every PipelineOptions::progress_every frames.
  virtual bool interactive() const { return false; }
};

// Lines on stderr: "<prefix>: <tag>: <text>", progress as "<prefix>: <line>", one updating line
// when stderr is a terminal. Messages less severe than `level` are dropped (progress is not).
class StderrLog final : public LogSink {
 public:
  explicit StderrLog(std::string prefix, LogLevel level = LogLevel::kDebug);
  void Write(LogLevel level, std::string_view tag, std::string_view text) override;
  void Progress(std::string_view line, bool final) override;
  bool interactive() const override { return tty_; }

 private:
  std::string prefix_;
  LogLevel level_;
  bool tty_;
};

// The log of a pipeline (or source) given none: StderrLog("sfrt pipeline").
LogSink& DefaultLog();

}  // namespace sfrt::pipeline
