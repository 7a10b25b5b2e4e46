// What `sfrt export` prints about a model it exported (or about the check that stopped it).
#pragma once

#include <string>
#include <vector>

#include "sfrt/exporter/export.h"

namespace sfrt::tools {

// The check's lines, as far as the check got (none when the model did not run).
std::vector<std::string> CheckLines(const exporter::CheckOptions& check,
                                    const exporter::CheckReport& report);

// The summary of a written model: source, layers, parameters, padding, shapes, input, camera,
// units, training, weights, file, the import's notes, the precision and calibration, the check.
void PrintExportReport(const exporter::ExportOptions& options,
                       const exporter::ExportResult& result);

}  // namespace sfrt::tools
