# Runs every command-line tool of the package with
#   --help               -> exit 0 and the usage printed on stdout;
#   --epochs 10x         -> a non-zero exit and a message naming --epochs (an unknown flag for most
#                           tools, a malformed number for train);
#   a numeric flag of the tool with a malformed value -> exit 2 and a message naming that flag;
#   with SOURCE_DIR, every docs/NAME.md and README "Section" the help names exists.
# and flags that cannot work together (evaluate --camera non-ois --stabiliser) -> exit 2 naming them.
# Usage: cmake -DTOOLS=/path/tool1;/path/tool2;... [-DSOURCE_DIR=<package>] -P check_tools_command_line.cmake
cmake_minimum_required(VERSION 3.16)
if(NOT TOOLS)
  message(FATAL_ERROR "pass -DTOOLS=<tool executables>")
endif()

# A numeric flag per tool and a value it must refuse ("" for a positional argument); tools without
# a numeric flag are absent.
set(NUMERIC_annotate_pairs "")
set(NUMERIC_benchmark_compensation "--frames;20x")
set(NUMERIC_benchmark_fundamental_mixtures ";60x")
set(NUMERIC_benchmark_gyro_flow "--frames;3.5")
set(NUMERIC_bag_static_transforms "")
set(NUMERIC_benchmark_simulator "--seed;-1")
set(NUMERIC_calibrate "--max-offset;0.1s")
set(NUMERIC_calibration_benchmark "")
set(NUMERIC_convert_recording "--clock-offset;1e")
set(NUMERIC_evaluate "--max-pairs;-3")
set(NUMERIC_evaluate_fundamental_mixtures "--sigma;nan")
set(NUMERIC_evaluate_lens_shift_ground_truth "--huber;0.3px")
set(NUMERIC_recover_bag "")
set(NUMERIC_fundamental_mixtures "")
set(NUMERIC_gyro_flow_summary "--idle-timeout;five")
set(NUMERIC_live_rate_monitor "--period;1min")
set(NUMERIC_make_calibration_configs "--count;24x")
set(NUMERIC_sim_contact_sheet "--seed;0x10")
set(NUMERIC_simulate "--duration;inf")
set(NUMERIC_train "--batch-size;8.5")
set(NUMERIC_train_stabiliser "--iterations;3.5")
set(NUMERIC_lens_log_fit "--split;6s")
set(NUMERIC_predict_lens "--warm-up;1s")
set(NUMERIC_benchmark_online_learning "--window;10s")
set(NUMERIC_benchmark_online_calibration "--window;10s")
set(NUMERIC_benchmark_lens_dynamics "--count;4.5")
set(NUMERIC_benchmark_linear_dynamics "--count;4.5")
set(NUMERIC_benchmark_fusion "--max-pairs;-3")
set(NUMERIC_benchmark_solver "--count;4.5")
set(NUMERIC_deprecated_launch_argument "")

set(failures "")
set(checked 0)
foreach(tool_path ${TOOLS})
  get_filename_component(tool "${tool_path}" NAME)
  math(EXPR checked "${checked} + 1")

  execute_process(COMMAND "${tool_path}" --help RESULT_VARIABLE status OUTPUT_VARIABLE out
                  ERROR_VARIABLE err TIMEOUT 60)
  if(NOT status EQUAL 0)
    string(APPEND failures "${tool} --help: exit ${status}, stderr: ${err}\n")
  elseif(NOT out MATCHES "Usage: ${tool}" OR NOT out MATCHES "--help")
    string(APPEND failures "${tool} --help: no usage on stdout: ${out}\n")
  elseif(SOURCE_DIR)
    # What the help points to exists: each docs/NAME.md, and each README "Section" as a heading.
    string(REGEX MATCHALL "docs/[A-Za-z0-9_/]+\\.md" documents "${out}")
    foreach(document ${documents})
      if(NOT EXISTS "${SOURCE_DIR}/${document}")
        string(APPEND failures "${tool} --help names ${document}, which does not exist\n")
      endif()
    endforeach()
    string(REGEX MATCHALL "README \"[^\"]+\"" sections "${out}")
    if(sections)
      file(READ "${SOURCE_DIR}/README.md" readme)
    endif()
    foreach(section ${sections})
      string(REGEX REPLACE "README \"([^\"]+)\"" "\\1" section "${section}")
      if(NOT readme MATCHES "\n#+ ${section}\n")
        string(APPEND failures "${tool} --help names the README section \"${section}\", which the README does not have\n")
      endif()
    endforeach()
  endif()

  execute_process(COMMAND "${tool_path}" --epochs 10x RESULT_VARIABLE status OUTPUT_VARIABLE out
                  ERROR_VARIABLE err TIMEOUT 60)
  if(status EQUAL 0)
    string(APPEND failures "${tool} --epochs 10x: exit 0\n")
  elseif(NOT err MATCHES "^${tool}: --epochs")
    string(APPEND failures "${tool} --epochs 10x: the message does not name --epochs: ${err}\n")
  endif()

  if(NOT DEFINED NUMERIC_${tool})
    string(APPEND failures "${tool}: not known to this check: add it to the NUMERIC_ list\n")
  elseif(NOT NUMERIC_${tool} STREQUAL "")
    list(GET NUMERIC_${tool} 0 flag)
    list(GET NUMERIC_${tool} 1 value)
    if(flag STREQUAL "")
      set(arguments "${value}")
      set(expected "^${tool}: pairs:")
    else()
      set(arguments "${flag};${value}")
      set(expected "^${tool}: ${flag}:")
    endif()
    execute_process(COMMAND "${tool_path}" ${arguments} RESULT_VARIABLE status OUTPUT_VARIABLE out
                    ERROR_VARIABLE err TIMEOUT 60)
    string(REPLACE ";" " " arguments "${arguments}")
    if(NOT status EQUAL 2)
      string(APPEND failures "${tool} ${arguments}: exit ${status} instead of 2: ${err}\n")
    elseif(NOT err MATCHES "${expected}")
      string(APPEND failures "${tool} ${arguments}: the message does not start with '${expected}': ${err}\n")
    endif()
  endif()
endforeach()

# Flags that cannot work together are refused naming the flag, not silently dropped.
# SOURCE_DIR (the package) holds the files the command lines name.
if(SOURCE_DIR)
  foreach(tool_path ${TOOLS})
    get_filename_component(tool "${tool_path}" NAME)
    if(tool STREQUAL "evaluate")
      # The stabiliser rows score OIS camera pairs only: none with --camera non-ois.
      execute_process(COMMAND "${tool_path}" --bags "${SOURCE_DIR}/bags/sample.bag"
                        --annotations "${SOURCE_DIR}/data/annotations/cc9pro.csv" --camera non-ois
                        --stabiliser "${SOURCE_DIR}/models/stabiliser_generic.yaml"
                      RESULT_VARIABLE status OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 60)
      if(NOT status EQUAL 2)
        string(APPEND failures "evaluate --camera non-ois --stabiliser: exit ${status} instead of 2: ${err}\n")
      elseif(NOT err MATCHES "^evaluate: --stabiliser: .*--camera ois")
        string(APPEND failures "evaluate --camera non-ois --stabiliser: the message does not name --stabiliser and --camera ois: ${err}\n")
      endif()
    endif()
  endforeach()
endif()

if(failures)
  message(FATAL_ERROR "command lines of ${checked} tools checked:\n${failures}")
endif()
message(STATUS "command lines of ${checked} tools: --help, --epochs 10x and a malformed number behave")
