// sfrt config check FILE...: validate deployment profiles (firmware-cfg/*.yaml) and say which of
// their process settings this process could apply.
#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "sfrt/commands.h"
#include "sfrt/config/capabilities.h"
#include "sfrt/config/profile.h"

namespace sfrt::tools {
namespace {

struct ConfigCheckArgs {
  std::vector<std::string> files;
  bool skip_capabilities = false;
  bool quiet = false;
};

std::string WarningLine(const config::Diagnostic& d) {
  // file:line:column: warning: key: problem
  config::Diagnostic copy = d;
  copy.key = copy.key.empty() ? "warning" : "warning: " + copy.key;
  return copy.ToString();
}

int RunConfigCheck(const ConfigCheckArgs& args) {
  const config::ProcessCapabilities caps = config::QueryProcessCapabilities();
  int failed = 0;
  for (const std::string& file : args.files) {
    config::ValidationReport report;
    Result<config::DeploymentProfile> profile = config::LoadProfile(file, &report);
    config::PrintErrors(report.errors, std::cerr);
    if (!profile.ok()) {
      ++failed;
      const size_t n = report.errors.size();
      std::cerr << "sfrt config check: " << file << ": " << n << (n == 1 ? " error" : " errors")
                << std::endl;
      continue;
    }
    // The checks `sfrt run` makes of its output directory before a run, so a profile that
    // passes here does not fail there.
    if (!profile->output_dir.empty()) {
      if (std::string problem = CheckWritableDirectory(profile->output_dir, "outputs.dir");
          !problem.empty()) {
        ++failed;
        std::cerr << "sfrt config check: " << file << ": " << problem << std::endl;
        continue;
      }
    }
    std::cout << file << ": OK\n";
    if (!args.quiet) std::cout << config::FormatProfileSummary(*profile);
    for (const config::Diagnostic& d : report.warnings) std::cout << WarningLine(d) << "\n";
    if (!args.skip_capabilities) {
      for (const config::CapabilityWarning& w : config::CheckCapabilities(*profile, caps)) {
        std::cout << file << ": warning: " << w.ToString() << "\n";
      }
    }
    std::cout.flush();
  }
  return failed == 0 ? kExitOk : kExitFailure;
}

}  // namespace

Command AddConfigCommand(CLI::App& parent) {
  CLI::App* cmd = parent.add_subcommand("config", "Validate deployment profiles (firmware-cfg/)");
  cmd->require_subcommand(1);
  auto args = std::make_shared<ConfigCheckArgs>();
  CLI::App* check = cmd->add_subcommand(
      "check", "Check profiles: keys, types, ranges, files; print a summary or every error");
  check->add_option("files", args->files, "Profile files (YAML)")->required();
  check->add_flag("--skip-capabilities", args->skip_capabilities,
                  "Do not check whether this process could apply the real-time priority, "
                  "mlockall and CPU affinity (e.g. when checking for another machine)");
  check->add_flag("-q,--quiet", args->quiet, "Print only 'FILE: OK', warnings and errors");
  check->footer(
      "For each FILE: parses the YAML profile (reference: firmware-cfg/README.md), checks every\n"
      "key, type, range and required key, that the model file exists and loads, that the\n"
      "calibration file(s) exist and parse, and that replay inputs exist. Relative paths resolve\n"
      "against the profile's directory.\n"
      "A valid profile prints 'FILE: OK' and a summary on stdout, then warnings: questionable\n"
      "settings, and settings this process may not apply (SCHED_FIFO priority without\n"
      "CAP_SYS_NICE or RLIMIT_RTPRIO, mlockall without CAP_IPC_LOCK or enough RLIMIT_MEMLOCK,\n"
      "CPUs outside the process's CPU set), each naming the setting and the fix.\n"
      "An invalid profile prints every error on stderr, one a line:\n"
      "  file:line:column: <key path>: <problem>; allowed: <values or range>\n"
      "then 'sfrt config check: FILE: N errors'.\n"
      "Exit codes: 0 every file valid (warnings allowed), 1 any file invalid, 2 usage error.");
  return Command{cmd, [args, check] {
                   if (check->parsed()) return RunConfigCheck(*args);
                   return ReportError("config", "no subcommand given (run 'sfrt config --help')",
                                      kExitUsage);
                 }};
}

}  // namespace sfrt::tools
