# Provides the imported target onnxruntime::onnxruntime.
#
# Order of preference:
#  1. -DONNXRUNTIME_ROOT=<dir> with include/onnxruntime/*.h and lib/libonnxruntime.so
#     (for example an official onnxruntime release, or a CUDA-enabled build);
#  2. otherwise the pinned copy in <build>/_deps/onnxruntime, fetched at configure time by
#     scripts/fetch-onnxruntime.sh (versions pinned in deps/onnxruntime.env).
#     With RAINDROP_ONNXRUNTIME_GPU=ON, the pinned onnxruntime-gpu build instead, in
#     <build>/_deps/onnxruntime-gpu: --device cuda then works where CUDA 13, cuDNN 9 and an
#     NVIDIA driver are on the library path. Off by default: the CPU build needs none of that.
set(ONNXRUNTIME_ROOT "" CACHE PATH "ONNX Runtime prefix (include/, lib/); empty = fetch the pinned copy")
option(RAINDROP_ONNXRUNTIME_GPU "Fetch the pinned GPU (CUDA) build of ONNX Runtime instead of the CPU one" OFF)

if(NOT ONNXRUNTIME_ROOT)
  if(RAINDROP_ONNXRUNTIME_GPU)
    set(ONNXRUNTIME_ROOT "${CMAKE_BINARY_DIR}/_deps/onnxruntime-gpu")
    set(_ort_fetch_flags --gpu)
  else()
    set(ONNXRUNTIME_ROOT "${CMAKE_BINARY_DIR}/_deps/onnxruntime")
    set(_ort_fetch_flags)
  endif()
  execute_process(
    COMMAND bash "${PROJECT_SOURCE_DIR}/scripts/fetch-onnxruntime.sh" ${_ort_fetch_flags} "${ONNXRUNTIME_ROOT}"
    RESULT_VARIABLE _ort_fetch_rc)
  if(NOT _ort_fetch_rc EQUAL 0)
    message(FATAL_ERROR "Could not obtain ONNX Runtime (scripts/fetch-onnxruntime.sh failed). "
                        "Pass -DONNXRUNTIME_ROOT=<prefix> to use an existing installation.")
  endif()
endif()

# NO_CACHE: found again at every configure, so switching RAINDROP_ONNXRUNTIME_GPU or
# ONNXRUNTIME_ROOT in an existing build folder takes effect (a cached path would keep the old one).
find_path(ONNXRUNTIME_INCLUDE_DIR onnxruntime_cxx_api.h
          PATHS "${ONNXRUNTIME_ROOT}/include/onnxruntime" "${ONNXRUNTIME_ROOT}/include"
          NO_DEFAULT_PATH REQUIRED NO_CACHE)
find_library(ONNXRUNTIME_LIBRARY NAMES onnxruntime PATHS "${ONNXRUNTIME_ROOT}/lib"
             NO_DEFAULT_PATH REQUIRED NO_CACHE)
add_library(onnxruntime::onnxruntime SHARED IMPORTED)
set_target_properties(onnxruntime::onnxruntime PROPERTIES
  IMPORTED_LOCATION "${ONNXRUNTIME_LIBRARY}"
  INTERFACE_INCLUDE_DIRECTORIES "${ONNXRUNTIME_INCLUDE_DIR}")
message(STATUS "ONNX Runtime: ${ONNXRUNTIME_LIBRARY} (headers ${ONNXRUNTIME_INCLUDE_DIR})")
