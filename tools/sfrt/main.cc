// sfrt: the command-line front end of the scene-flow runtime.
//   sfrt export  model.onnx -o model.sfrt   convert a trained network into a .sfrt model file
//                                           (built with the exporter only)
//   sfrt inspect model.sfrt                 metadata, per-layer shapes and costs, arena size
//   sfrt infer   --model model.sfrt ...     run one frame pair and write the scene flow
#include <signal.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include "sfrt/commands.h"
#include "sfrt/config/limits.h"
#include "sfrt/config/profile.h"
#include "sfrt/model.h"
#include "sfrt/pipeline/io/atomic_write.h"

#ifndef SFRT_WITH_EXPORTER
#define SFRT_WITH_EXPORTER 0
#endif
#ifndef SFRT_VERSION
#define SFRT_VERSION "unknown"
#endif

namespace sfrt::tools {

int ReportError(std::string_view command, std::string_view message, int exit_code) {
  std::string line = "sfrt";
  if (!command.empty()) {
    line += " ";
    line += command;
  }
  line += ": ";
  for (char c : message) line.push_back(c == '\n' || c == '\r' ? ' ' : c);
  while (!line.empty() && line.back() == ' ') line.pop_back();
  std::cerr << line << std::endl;
  return exit_code;
}

bool ParseSize(std::string_view text, int* height, int* width) {
  size_t sep = text.find_first_of("xX,");
  if (sep == std::string_view::npos) return false;
  auto parse = [](std::string_view part, int* out) {
    const char* end = part.data() + part.size();
    auto [ptr, ec] = std::from_chars(part.data(), end, *out);
    return !part.empty() && ec == std::errc() && ptr == end && *out > 0;
  };
  return parse(text.substr(0, sep), height) && parse(text.substr(sep + 1), width);
}

Result<std::shared_ptr<const Model>> LoadModelFile(const std::string& path) {
  if (std::string problem = CheckInputFile(path, "model file"); !problem.empty()) {
    return Status::Error(problem);
  }
  return Model::LoadFile(path);
}

std::string CheckInputFile(const std::string& path, std::string_view what) {
  std::error_code ec;
  std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st)) {
    return std::string(what) + " '" + path + "' does not exist";
  }
  if (std::filesystem::is_directory(st)) {
    return std::string(what) + " '" + path + "' is a directory";
  }
  return "";
}

std::string CheckOutputFile(const std::string& path, std::string_view flag) {
  Result<io::OutputTarget> target = io::ResolveOutputTarget(path);
  if (!target.ok()) return std::string(flag) + ": " + target.message();
  if (target->kind == io::OutputTarget::Kind::kInPlace) return "";  // a device or FIFO
  const std::filesystem::path parent = std::filesystem::path(target->path).parent_path();
  std::error_code ec;
  if (!parent.empty() && !std::filesystem::is_directory(parent, ec)) {
    return "output directory '" + parent.string() + "' does not exist (for " + std::string(flag) +
           " " + path + ")";
  }
  // The file is written to a temporary name beside it and renamed: the directory must take one.
  return io::CheckWritableDirectory(parent.empty() ? "." : parent.string(),
                                    std::string(flag) + " " + path + ": its directory");
}

std::string CheckWritableDirectory(const std::string& path, std::string_view flag) {
  return io::CheckWritableDirectory(path, flag);
}

namespace {

std::string BoundProblem(std::string_view flag, double value, const char* rule, double bound) {
  return std::string(flag) + ": " + FormatFloat(value) + " is not " + rule + " " +
         FormatFloat(bound);
}

}  // namespace

std::string CheckAtLeast(std::string_view flag, double value, double lo) {
  return value >= lo ? std::string() : BoundProblem(flag, value, ">=", lo);
}

std::string CheckAbove(std::string_view flag, double value, double lo) {
  return value > lo ? std::string() : BoundProblem(flag, value, ">", lo);
}

std::string CheckAtMost(std::string_view flag, double value, double hi) {
  return value <= hi ? std::string() : BoundProblem(flag, value, "<=", hi);
}

CLI::Option* RequireAtLeast(CLI::Option* option, double lo) {
  return option->check(CLI::Validator(
      [lo](std::string& text) {
        double value = 0;
        if (!config::ParseFiniteNumber(text, &value)) return "'" + text + "' is not a number";
        return value >= lo ? std::string() : text + " is not >= " + FormatFloat(lo);
      },
      "", "at least"));
}

namespace {

// Set by the SIGINT/SIGTERM handler; read by the pipeline's watcher thread or synth's writer.
std::atomic<bool> g_stop{false};
std::atomic<int> g_signal{0};
static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<int>::is_always_lock_free);

extern "C" void OnStopSignal(int sig) {
  g_signal.store(sig);
  g_stop.store(true);
}

}  // namespace

StopSignals CatchStopSignals() {
  struct sigaction action = {};
  action.sa_handler = OnStopSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  return {&g_stop, &g_signal};
}

std::string LowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

std::string FormatFloat(double value) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", value);
  return buf;
}

std::string Join(const std::vector<std::string>& items, const char* sep) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : sep) + item;
  return out;
}

std::string GroupDigits(unsigned long long value) {
  std::string digits = std::to_string(value);
  std::string out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out.push_back(',');
    out.push_back(digits[i]);
  }
  return out;
}

const char* DefaultInputSize(const ModelMetadata& meta, int* height, int* width) {
  if (meta.input.traced_height > 0 && meta.input.traced_width > 0) {
    *height = meta.input.traced_height;
    *width = meta.input.traced_width;
    return "traced size";
  }
  *height = kFallbackInputHeight;
  *width = kFallbackInputWidth;
  return "default; traced size unknown";
}

}  // namespace sfrt::tools

namespace {

// The subcommand named on the command line, for error messages when parsing failed before
// CLI11 recorded it.
std::string CommandName(const CLI::App& app, int argc, char** argv) {
  std::vector<CLI::App*> parsed = app.get_subcommands();
  if (!parsed.empty()) return parsed.front()->get_name();
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    for (const CLI::App* sub : app.get_subcommands({})) {
      if (sub->get_name() == arg) return arg;
    }
  }
  return "";
}

// When an option is followed by several existing files, the shell most likely expanded an
// unquoted glob into them (CLI11 then calls all but the first "not expected"): a message that
// says so and how to quote it, or "" when the command line does not look like that.
std::string ExpandedGlobHint(int argc, char** argv) {
  for (int i = 1; i + 2 < argc; ++i) {
    const std::string option = argv[i];
    if (option.rfind("--", 0) != 0 || option.find('=') != std::string::npos) continue;
    int files = 0;
    std::error_code ec;
    while (i + 1 + files < argc && argv[i + 1 + files][0] != '-' &&
           std::filesystem::exists(argv[i + 1 + files], ec)) {
      ++files;
    }
    if (files < 2) continue;
    const std::filesystem::path first(argv[i + 1]);
    const std::string dir = first.parent_path().empty() ? "." : first.parent_path().string();
    return option + " was given " + std::to_string(files) + " files ('" + argv[i + 1] + "', '" +
           argv[i + 2] + "', ...): the shell expanded an unquoted glob; quote the " +
           "pattern so sfrt expands it, e.g. " + option + " '" + dir + "/*" +
           first.extension().string() + "'";
  }
  return "";
}

// "unknown option --modle (did you mean --model?)" for the first long option on the command
// line that the (sub)command it follows does not have; "" when every option is known. CLI11
// would report a missing required option first, which hides the typo.
std::string UnknownOption(const CLI::App& app, int argc, char** argv) {
  const CLI::App* cmd = &app;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--") break;
    if (arg.rfind("--", 0) != 0) {
      for (const CLI::App* sub : cmd->get_subcommands({})) {
        if (sub->get_name() == arg) cmd = sub;
      }
      continue;
    }
    const std::string name = arg.substr(0, arg.find('='));
    if (name == "--help" || name.size() < 3 || cmd->get_option_no_throw(name) != nullptr) continue;
    std::string best;
    int best_distance = 1 << 30;
    for (const CLI::Option* opt : cmd->get_options()) {
      for (const std::string& lname : opt->get_lnames()) {
        const int d = sfrt::config::EditDistance(name.substr(2), lname);
        if (d < best_distance) {
          best_distance = d;
          best = "--" + lname;
        }
      }
    }
    const int limit = std::max(2, static_cast<int>(name.size() - 2) / 3);
    return "unknown option " + name +
           (best_distance <= limit ? " (did you mean " + best + "?)" : std::string());
  }
  return "";
}

// Every real-valued option of every command (CLI11 types them FLOAT) is read by the one shared
// parser (config::ParseFiniteNumber): "nan" and "inf" are refused naming the option, so no NaN
// can mean "no budget" or slip past a range check. Walks the commands once, after they are added.
void RequireFiniteNumbers(CLI::App* app) {
  const CLI::Validator finite(
      [](std::string& text) {
        double value = 0;
        return sfrt::config::ParseFiniteNumber(text, &value)
                   ? std::string()
                   : "'" + text + "' is not a finite number";
      },
      "", "finite");
  for (CLI::Option* option : app->get_options()) {
    if (option->get_type_name().rfind("FLOAT", 0) == 0) option->check(finite);
  }
  for (CLI::App* sub : app->get_subcommands([](CLI::App*) { return true; })) {
    RequireFiniteNumbers(sub);
  }
}

}  // namespace

int main(int argc, char** argv) {
  using sfrt::tools::kExitFailure;
  using sfrt::tools::kExitOk;
  using sfrt::tools::kExitUsage;
  using sfrt::tools::ReportError;

  CLI::App app{"sfrt: SceneEDNet scene-flow runtime tools.", "sfrt"};
  app.set_version_flag("--version", std::string("sfrt ") + SFRT_VERSION + " (model schema " +
                                        std::to_string(sfrt::kSchemaVersionMajor) + "." +
                                        std::to_string(sfrt::kSchemaVersionMinor) + ")");
  app.require_subcommand(1);
  app.footer(
      "Run 'sfrt <command> --help' for a command's options.\n"
      "Exit codes: 0 success, 1 runtime or input failure, 2 usage error.");

  std::vector<sfrt::tools::Command> commands;
#if SFRT_WITH_EXPORTER
  commands.push_back(sfrt::tools::AddExportCommand(app));
#endif
  commands.push_back(sfrt::tools::AddInspectCommand(app));
  commands.push_back(sfrt::tools::AddInferCommand(app));
  commands.push_back(sfrt::tools::AddBenchCommand(app));
  commands.push_back(sfrt::tools::AddSynthCommand(app));
  commands.push_back(sfrt::tools::AddAnnotateCommand(app));
  commands.push_back(sfrt::tools::AddRunCommand(app));
  commands.push_back(sfrt::tools::AddEvalCommand(app));
  commands.push_back(sfrt::tools::AddMergeCommand(app));
  commands.push_back(sfrt::tools::AddConfigCommand(app));
  commands.push_back(sfrt::tools::AddReportCommand(app));
  RequireFiniteNumbers(&app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  } catch (const CLI::ParseError& e) {
    std::string name = CommandName(app, argc, argv);
    std::string hint = name.empty() ? "run 'sfrt --help'" : "run 'sfrt " + name + " --help'";
    const std::string unknown = UnknownOption(app, argc, argv);
    std::string message = unknown.empty() ? std::string(e.what()) : unknown;
    if (dynamic_cast<const CLI::ExtrasError*>(&e) != nullptr) {
      if (std::string glob = ExpandedGlobHint(argc, argv); !glob.empty()) message = glob;
    }
    return ReportError(name, message + " (" + hint + ")", kExitUsage);
  }

  for (const sfrt::tools::Command& command : commands) {
    if (!command.app->parsed()) continue;
    const std::string& name = command.app->get_name();
    try {
      return command.run();
    } catch (const std::bad_alloc&) {
      return ReportError(name, "out of memory", kExitFailure);
    } catch (const std::exception& e) {
      return ReportError(name, e.what(), kExitFailure);
    }
  }
  return ReportError("", "no command given (run 'sfrt --help')", kExitUsage);
}
