# Fails when the runtime library refers to getenv or secure_getenv: the library takes options and
# reads no environment (docs/architecture.md). Usage: cmake -DNM=<nm> -DLIB=<archive> -P <this>
execute_process(COMMAND ${NM} -u ${LIB} OUTPUT_VARIABLE undefined RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} -u ${LIB} failed (${rc})")
endif()
# nm must have listed the library's imports, or the check below proves nothing.
if(NOT undefined MATCHES "[ \t]U[ \t]+(memcpy|memset|free)")
  message(FATAL_ERROR "${NM} -u ${LIB} listed none of memcpy, memset, free:\n${undefined}")
endif()
string(REGEX MATCHALL "[ \t]U[ \t]+(secure_)?getenv[^\n]*" found "${undefined}")
if(found)
  message(FATAL_ERROR "${LIB} refers to ${found}: the runtime must read no environment variable")
endif()
message(STATUS "${LIB}: no getenv or secure_getenv")
