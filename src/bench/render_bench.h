#pragma once
// raindrop-bench render: the renderer's time and accuracy/time tables (markdown on stdout).
namespace raindrop {
int render_bench(int argc, char** argv);
}
