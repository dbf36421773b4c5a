// dejag/app: each subcommand registers itself on the top-level CLI::App.
#pragma once

#include <CLI/CLI.hpp>

namespace dejag::cli {

void registerMetricsCommand(CLI::App& app);
void registerBenchCommand(CLI::App& app);
void registerRenderCommand(CLI::App& app);
void registerDataCommand(CLI::App& app);
void registerTrainCommand(CLI::App& app);
void registerDemoCommand(CLI::App& app);
void registerFilterCommand(CLI::App& app);
void registerCompletionCommand(CLI::App& app);
void registerExportCommand(CLI::App& app);
void registerViewCommand(CLI::App& app);

}  // namespace dejag::cli
