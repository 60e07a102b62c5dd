#pragma once
// raindrop-bench remove: raindrop-remove's time per image and per stage, and the GFLOP/s the
// three networks reach (markdown tables on stdout, progress on stderr).
#include <functional>

#include <CLI/CLI.hpp>

namespace raindrop {

// Adds the `remove` subcommand and its options to `app`; the returned function runs it once
// `app` has parsed the command line, and returns the exit code (2 for options that parse but
// do not fit together).
std::function<int()> add_remove_bench(CLI::App& app);

}  // namespace raindrop
