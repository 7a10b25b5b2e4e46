# The FlatBuffers model writer: model_writer.cc and each layer kind's writer (src/writers/). It
# needs only the runtime and the schema header, so the exporter compiles it and runtime-only
# builds (the aarch64 preset) compile it for their tests too (tests/common).
set(SFRT_MODEL_WRITER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/src/model_writer.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/add.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/channel_affine.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/concat.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/conv2d.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/conv_transpose2d.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/crop.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/layer_writer.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/pool2d.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/resize.cc
  ${CMAKE_CURRENT_LIST_DIR}/src/writers/upsample.cc)
