// sfrt: the command-line front end of the scene-flow runtime.
//   sfrt export  model.onnx -o model.sfrt   convert a trained network into a .sfrt model file
//                                           (built with the exporter only)
//   sfrt inspect model.sfrt                 metadata, per-layer shapes and costs, arena size
//   sfrt infer   --model model.sfrt ...     run one frame pair and write the scene flow
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
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
#include "sfrt/config/profile.h"
#include "sfrt/model.h"

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

std::string CheckOutputDirectory(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (parent.empty() || std::filesystem::is_directory(parent, ec)) return "";
  return "output directory '" + parent.string() + "' does not exist (for -o " + path + ")";
}

std::string CheckWritableDirectory(const std::string& path, std::string_view flag) {
  namespace fs = std::filesystem;
  const std::string head = std::string(flag) + " '" + path + "': ";
  fs::path dir = fs::path(path).lexically_normal();
  if (!dir.empty() && dir.filename().empty()) dir = dir.parent_path();  // "out/" -> "out"
  std::error_code ec;
  while (!dir.empty() && !fs::exists(fs::symlink_status(dir, ec)) && !fs::exists(dir, ec)) {
    dir = dir.parent_path();
  }
  if (dir.empty()) dir = ".";
  if (!fs::is_directory(dir, ec)) {
    return head + "'" + dir.string() + "' exists and is not a directory";
  }
  std::string probe = (dir / ".sfrt-write-test-XXXXXX").string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0) {
    return head + "cannot create files in '" + dir.string() + "' (" + std::strerror(errno) + ")";
  }
  ::close(fd);
  ::unlink(probe.c_str());
  return "";
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
  commands.push_back(sfrt::tools::AddConfigCommand(app));
  commands.push_back(sfrt::tools::AddReportCommand(app));

  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  } catch (const CLI::ParseError& e) {
    std::string name = CommandName(app, argc, argv);
    std::string hint = name.empty() ? "run 'sfrt --help'" : "run 'sfrt " + name + " --help'";
    const std::string unknown = UnknownOption(app, argc, argv);
    return ReportError(
        name, (unknown.empty() ? std::string(e.what()) : unknown) + " (" + hint + ")", kExitUsage);
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
