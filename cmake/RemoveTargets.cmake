# raindrop-remove: the removal pipeline library, its command-line program, its benchmark
# (raindrop-bench remove) and install rules. Included by the root CMakeLists.txt after the
# raindrop_render and raindrop-bench targets exist.

# The ONNX Runtime library file (its SONAME link, libonnxruntime.so.1, is made by
# scripts/fetch-onnxruntime.sh), for the install rules below.
get_target_property(_ort_lib onnxruntime::onnxruntime IMPORTED_LOCATION)
get_filename_component(_ort_lib_dir "${_ort_lib}" DIRECTORY)
file(REAL_PATH "${_ort_lib}" _ort_real)

add_library(raindrop_remove STATIC
  src/remove/edge_map.cpp
  src/remove/mask.cpp
  src/remove/model.cpp
  src/remove/model_paths.cpp
  src/remove/pixels.cpp
  src/remove/remover.cpp
  src/remove/session.cpp
  src/remove/stage_times.cpp
  src/remove/tiling.cpp
  src/remove/working_scale.cpp)
target_include_directories(raindrop_remove PUBLIC ${PROJECT_SOURCE_DIR}/include)
target_link_libraries(raindrop_remove PUBLIC raindrop_render onnxruntime::onnxruntime)
# Step 4 of the model search: the source tree's models/ (for programs run from the build tree).
target_compile_definitions(raindrop_remove PRIVATE RAINDROP_SOURCE_MODELS_DIR="${PROJECT_SOURCE_DIR}/models")

add_executable(raindrop-remove src/cli/remove_main.cpp)
target_link_libraries(raindrop-remove PRIVATE raindrop_remove CLI11::CLI11)
target_compile_definitions(raindrop-remove PRIVATE RAINDROP_VERSION="${PROJECT_VERSION}")
# Installed: bin/raindrop-remove finds lib/libonnxruntime.so.1 next to it.
set_target_properties(raindrop-remove PROPERTIES INSTALL_RPATH "$ORIGIN/../lib")

# raindrop-bench remove
target_sources(raindrop-bench PRIVATE src/bench/remove_bench.cpp)
target_link_libraries(raindrop-bench PRIVATE raindrop_remove nlohmann_json::nlohmann_json)
target_compile_definitions(raindrop-bench PRIVATE RAINDROP_HAVE_REMOVE_BENCH)

# Install: the program, the ONNX Runtime library under its SONAME, and the trained models
# (share/raindrop/models/<config>/{rdn,rrn,rfn}.onnx, export.json, and DEFAULT).
install(TARGETS raindrop-remove RUNTIME DESTINATION bin)
install(FILES "${_ort_real}" DESTINATION lib RENAME libonnxruntime.so.1)
# A CUDA-enabled ONNX Runtime (-DONNXRUNTIME_ROOT) loads its providers from beside itself.
file(GLOB _ort_providers "${_ort_lib_dir}/libonnxruntime_providers_*.so")
if(_ort_providers)
  install(FILES ${_ort_providers} DESTINATION lib)
endif()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/models/ DESTINATION share/raindrop/models
        FILES_MATCHING PATTERN "DEFAULT" PATTERN "*.onnx" PATTERN "export.json" PATTERN "*.md")
