#pragma once
// raindrop-bench render: the renderer's time and accuracy/time tables (markdown on stdout).
#include <functional>

#include <CLI/CLI.hpp>

namespace raindrop {

// Adds the `render` subcommand and its options to `app`; the returned function runs it once
// `app` has parsed the command line, and returns the exit code.
std::function<int()> add_render_bench(CLI::App& app);

}  // namespace raindrop
