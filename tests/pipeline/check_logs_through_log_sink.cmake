# Fails when an object of the pipeline library other than log.cc.o refers to stderr, stdout or
# the functions and streams that write to them: the library's messages go through its LogSink
# (pipeline/log.h). Usage: cmake -DNM=<nm> -DLIB=<archive> -P <this>
execute_process(COMMAND ${NM} -A -u ${LIB} OUTPUT_VARIABLE undefined RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} -A -u ${LIB} failed (${rc})")
endif()
# The check must see the imports: log.cc.o, the one writer, refers to stderr.
if(NOT undefined MATCHES "log\\.cc\\.o:[ \t]+U[ \t]+stderr")
  message(FATAL_ERROR "${NM} did not list log.cc.o's use of stderr, so the check proves nothing:\n${undefined}")
endif()
set(writers "stderr|stdout|printf|fprintf|vfprintf|puts|fputs|perror|_ZSt4cerr|_ZSt4cout|_ZSt4clog")
string(REGEX MATCHALL "[^\n]*:[ \t]+U[ \t]+(${writers})\n" found "${undefined}\n")
set(offenders "")
foreach(line IN LISTS found)
  if(NOT line MATCHES "log\\.cc\\.o:")
    string(APPEND offenders "${line}")
  endif()
endforeach()
if(offenders)
  message(FATAL_ERROR "writes around the LogSink (pipeline/log.h):\n${offenders}")
endif()
message(STATUS "${LIB}: only log.cc.o writes to stderr")
