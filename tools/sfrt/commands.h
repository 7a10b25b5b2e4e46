// The `sfrt` subcommands. Each cmd_*.cc registers one subcommand on the CLI11 app and returns
// the function that runs it once the command line has been parsed.
//
// Exit codes (all subcommands): 0 success, 1 runtime or input failure (unreadable or invalid
// files, a model that fails to load or run), 2 usage error (bad flags or flag values, detected
// before any file is read). Errors go to stderr as one line: "sfrt <command>: <message>".
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "sfrt/status.h"

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace sfrt {
struct ModelMetadata;
class Model;
}  // namespace sfrt

namespace sfrt::tools {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;

// A registered subcommand: its CLI11 app, and what to run when the command line selected it.
// `run` returns the process exit code.
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

Command AddExportCommand(CLI::App& parent);
Command AddInspectCommand(CLI::App& parent);
Command AddInferCommand(CLI::App& parent);
Command AddBenchCommand(CLI::App& parent);
Command AddSynthCommand(CLI::App& parent);
Command AddAnnotateCommand(CLI::App& parent);
Command AddRunCommand(CLI::App& parent);
Command AddEvalCommand(CLI::App& parent);
Command AddMergeCommand(CLI::App& parent);
Command AddConfigCommand(CLI::App& parent);
Command AddReportCommand(CLI::App& parent);

// Prints "sfrt <command>: <message>" on one line to stderr (newlines in `message` become
// spaces) and returns `exit_code`.
int ReportError(std::string_view command, std::string_view message, int exit_code);

// Parses "HxW" (also "HXW" or "H,W") into positive height and width.
bool ParseSize(std::string_view text, int* height, int* width);

// The input size of a model-running command without --size (inspect, bench): the size the
// model was traced at, else kFallbackInputHeight x kFallbackInputWidth (the Scene Flow frame
// size). Returns how it was chosen, for the output: "traced size" or "default; traced size
// unknown".
inline constexpr int kFallbackInputHeight = 540;
inline constexpr int kFallbackInputWidth = 960;
const char* DefaultInputSize(const ModelMetadata& meta, int* height, int* width);

// Empty when `path` names an existing regular file (or a symlink to one); otherwise a message
// such as "model file 'x.sfrt' does not exist". `what` names the role ("model file").
std::string CheckInputFile(const std::string& path, std::string_view what);

// The model file at `path`, loaded and verified: CheckInputFile's message for a missing file,
// else the loader's (each names the file).
Result<std::shared_ptr<const Model>> LoadModelFile(const std::string& path);

// Empty when an output file could be written at `path` (by io::WriteFileAtomically's rule): its
// directory exists and takes a new file, or it is a device or FIFO; otherwise a message naming
// `flag` and the reason, e.g. "output directory 'out' does not exist (for -o out/flow.pfm)".
// Commands call it before they compute, so a result is never lost to an unwritable path.
std::string CheckOutputFile(const std::string& path, std::string_view flag);

// Empty when files can be created in the directory `path`, or, if it does not exist yet, in its
// nearest existing ancestor (so creating it would work); otherwise a message naming `flag`, the
// path and the reason. Tests by creating and removing a file: nothing is left behind.
std::string CheckWritableDirectory(const std::string& path, std::string_view flag);

// Numeric bounds on values already parsed, each problem naming its option and value
// ("--budget-ms: -5 is not >= 0"); "" when the value is within them. For values that may come
// from a profile too, checked once the command line and the profile are merged.
std::string CheckAtLeast(std::string_view flag, double value, double lo);
std::string CheckAbove(std::string_view flag, double value, double lo);
std::string CheckAtMost(std::string_view flag, double value, double hi);
// The same rule as a CLI11 check on `option`, at parse time: "--loop: 0 is not >= 1".
CLI::Option* RequireAtLeast(CLI::Option* option, double lo);

// SIGINT and SIGTERM, caught for the rest of the process: `stop` is set and `signal` says which
// (0: none yet). Commands that run long (run, synth) poll them, finish or remove what they were
// writing, and exit; a second call returns the same flags.
struct StopSignals {
  const std::atomic<bool>* stop;
  const std::atomic<int>* signal;
};
StopSignals CatchStopSignals();

// Lower-cased extension of `path` including the dot (".onnx"), or "" if it has none.
std::string LowerExtension(const std::string& path);

// Number with thousands separators: 1234567 -> "1,234,567".
std::string GroupDigits(unsigned long long value);

// Shortest natural form of a number, as printf's %g: 1050, 479.5, 0.3, 1e-05.
std::string FormatFloat(double value);

// The items with `sep` between them: {"left0", "right0"}, "," -> "left0,right0".
std::string Join(const std::vector<std::string>& items, const char* sep);

}  // namespace sfrt::tools
