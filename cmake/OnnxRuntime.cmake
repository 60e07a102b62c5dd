# Provides the imported target onnxruntime::onnxruntime.
#
# Order of preference:
#  1. -DONNXRUNTIME_ROOT=<dir> with include/onnxruntime/*.h and lib/libonnxruntime.so
#     (for example an official onnxruntime release, or a CUDA-enabled build);
#  2. otherwise the pinned copy in <build>/_deps/onnxruntime, fetched at configure time by
#     scripts/fetch-onnxruntime.sh (versions pinned in deps/onnxruntime.env).
set(ONNXRUNTIME_ROOT "" CACHE PATH "ONNX Runtime prefix (include/, lib/); empty = fetch the pinned copy")

if(NOT ONNXRUNTIME_ROOT)
  set(ONNXRUNTIME_ROOT "${CMAKE_BINARY_DIR}/_deps/onnxruntime")
  execute_process(
    COMMAND bash "${PROJECT_SOURCE_DIR}/scripts/fetch-onnxruntime.sh" "${ONNXRUNTIME_ROOT}"
    RESULT_VARIABLE _ort_fetch_rc)
  if(NOT _ort_fetch_rc EQUAL 0)
    message(FATAL_ERROR "Could not obtain ONNX Runtime (scripts/fetch-onnxruntime.sh failed). "
                        "Pass -DONNXRUNTIME_ROOT=<prefix> to use an existing installation.")
  endif()
endif()

find_path(ONNXRUNTIME_INCLUDE_DIR onnxruntime_cxx_api.h
          PATHS "${ONNXRUNTIME_ROOT}/include/onnxruntime" "${ONNXRUNTIME_ROOT}/include"
          NO_DEFAULT_PATH REQUIRED)
find_library(ONNXRUNTIME_LIBRARY NAMES onnxruntime PATHS "${ONNXRUNTIME_ROOT}/lib"
             NO_DEFAULT_PATH REQUIRED)
add_library(onnxruntime::onnxruntime SHARED IMPORTED)
set_target_properties(onnxruntime::onnxruntime PROPERTIES
  IMPORTED_LOCATION "${ONNXRUNTIME_LIBRARY}"
  INTERFACE_INCLUDE_DIRECTORIES "${ONNXRUNTIME_INCLUDE_DIR}")
message(STATUS "ONNX Runtime: ${ONNXRUNTIME_LIBRARY} (headers ${ONNXRUNTIME_INCLUDE_DIR})")
