"""`make mutate`: break the code on purpose, one curated mutation at a time, and check that a fast test fails.

Each mutation is a textual replacement of an exact snippet (found exactly once) in a temporary copy of the package;
the working tree is never touched. The copy carries the tree's numba cache (``__pycache__``, sources' timestamps
kept), so only the mutated file's kernels are recompiled. Each mutant's chosen tests run in a fresh process
(``pytest -x``, stopping at the first failure): the mutation is *killed* when one fails, *survived* when all pass.
A baseline run of every chosen test on an unmutated copy comes first (it must pass, and it warms the cache the
mutants copy). Exits non-zero when any mutation survives (or the baseline fails).

Usage: python benches/mutate.py [--only NAME ...] [--list] [--json benches/results/mutate.json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

RAD8 = "tests/test_sar_radiometry.py::test_isolated_point_targets_focus_to_the_radar_equation[8]"
TWELVE = "tests/test_sar_focus.py::test_twelve_channels_focus_too"
GEOTIFF = "tests/test_sar_focus.py::test_geotiff_puts_reflectors_at_their_utm_position"
UTM_ANYWHERE = "tests/test_image_products.py::test_geotiff_is_in_the_utm_zone_of_the_origin_anywhere"
QUICKLOOK_POOLED = "tests/test_quicklook.py::test_quicklook_axes_put_a_pooled_pixel_at_its_pixels_metres"
BP_REF = "tests/test_sar_backprojection.py::test_kernel_equals_float64_reference_straight_track"
RANGE_REF = "tests/test_sar_range.py::test_matches_the_float64_reference_on_random_data"
BEAT_REF = "tests/test_sim_kernels.py::test_beat_kernel_matches_float64_reference"
ENGINES = "tests/test_nav_sarmin.py::test_compiled_filter_equals_the_filterpy_reference[white-0.0-False-False]"
SENSORS = "tests/test_nav_sarmin.py::test_every_sensor_counts"
NAV_CI = "tests/test_nav_sarmin.py::test_sarmin_accuracy_on_ci"
CAN_SI = "tests/test_ingest_roundtrip.py::test_can_values_in_si_within_quantisation"
CAN_UNITS = "tests/test_candb.py::test_dbc_units_convert_to_si_by_the_textbook_factors"
NMEA_SIM = "tests/test_ingest_nmea.py::test_simulator_round_trip"
WHEEL_LAG = "tests/test_nav_models.py::test_each_wheel_is_moved_by_its_own_window_in_a_turn"
PASS_DOPPLER = "tests/test_pass_ranges.py::test_the_envelopes_doppler_shift_is_the_beat_frequencys"
PASS_INJECTED = "tests/test_pass_ranges.py::test_recovers_an_injected_along_track_error"
FOREIGN = "tests/test_safety.py::test_overwrite_never_replaces_a_directory_or_a_foreign_file"
OWN_INPUT = "tests/test_safety.py::test_ingest_output_same_as_its_log_is_refused"
INSIDE_INPUT = "tests/test_safety.py::test_compare_output_inside_its_rosbag2_log_is_refused"
STALE = "tests/test_safety.py::test_stale_partial_of_a_killed_ingest_is_listed_and_removed_by_the_next_command"
DEGRADED = "tests/test_safety.py::test_run_of_a_truncated_log_says_it_is_degraded"
CUBE_CRC = "tests/test_integrity.py::test_a_flipped_byte_in_the_radar_cube_is_an_error_naming_file_and_dataset"
TRACK_CRC = "tests/test_integrity.py::test_a_flipped_byte_in_a_trajectory_is_an_error_naming_file_and_dataset"
OTHER_RECORDING = "tests/test_evaluate.py::test_another_recordings_trajectory_is_refused"
CAN_FAULTS = "tests/test_ingest_robustness.py::test_can_integrity_faults_counted_never_fatal"
NMEA_BAD = "tests/test_ingest_nmea.py::test_bad_input_is_counted_not_raised"
DCA_LAYOUTS = "tests/test_ingest_dca1000.py::test_layout_round_trips"
DCA_NARROW = "tests/test_ingest_dca1000.py::test_narrow_adc_samples_are_sign_extended"
DCA_ZEROS = "tests/test_ingest_dca1000.py::test_zero_filled_packets_of_post_processed_data_are_left_out"
DCA_CLI_CONFIG = "tests/test_ingest_dca1000.py::test_the_dca1000_clis_config_beside_an_sdk_capture_must_agree"
UNDERSTEER = ("tests/test_nav_models.py::"
              "test_understeer_fit_finds_the_full_vehicles_gradient_and_none_on_a_kinematic_car")
STANDSTILL = "tests/test_nav_models.py::test_a_standstill_is_where_all_four_wheels_read_zero_and_the_car_stands"
GNSS_DELAYED = "tests/test_nav_gnss_latency.py::test_delayed_gnss_moves_every_gnss_stream_and_nothing_else"
CAN_LATE = "tests/test_nav_can_latency.py::test_the_can_gyros_delay_against_the_imus_is_found_within_its_std"
TURNED = "tests/test_nav_realdata.py::test_sensor_to_body_is_the_mounting_rotation_and_keeps_a_3dof_yaw_rate"
GRAVITY_TILT = "tests/test_nav_realdata.py::test_an_imu_mounted_turned_is_refused_with_where_its_gravity_reads"
IN_G = "tests/test_nav_sarmin.py::test_an_imu_logging_its_accelerations_in_g_is_refused"
LEVELLING = "tests/test_nav_realdata.py::test_the_levelling_pitch_and_roll_turn_gravity_onto_up"
FIRST_MOVE = "tests/test_nav_realdata.py::test_the_first_move_of_fixes_alone_is_their_course_and_speed"
FIXES_ALONE = "tests/test_nav_realdata.py::test_sarmin_starts_from_the_fixes_alone_on_a_real_robot"
FIX_VELOCITY = "tests/test_nav_realdata.py::test_the_fixes_own_velocity_is_their_central_difference"
GATED_GYRO = "tests/test_nav_sarmin.py::test_a_gyro_the_gate_refuses_is_warned_of"
CONFIG_BASE = "tests/test_config.py::test_a_config_on_a_base_holds_only_what_differs"
CUT_SHORT = "tests/test_integrity.py::test_a_product_cut_short_says_by_how_much"
CUBE_DAMAGE = "tests/test_integrity.py::test_a_damaged_radar_chunk_costs_only_its_frames"
FOCUS_DAMAGE = ("tests/test_integrity.py::"
                "test_focus_of_a_drive_damaged_in_a_radar_chunk_leaves_out_its_frames_and_says_so[1]")
TABLE_DAMAGE = "tests/test_integrity.py::test_a_damaged_table_chunk_costs_only_its_rows"
CAN_VELOCITY = "tests/test_nav_realdata.py::test_a_can_receivers_speed_and_course_are_its_velocity"
TWICE_NAMED = "tests/test_ingest_realdata.py::test_a_role_names_one_of_two_frame_ids_a_dbc_gives_one_name"
BY_WHAT_IT_HOLDS = "tests/test_ingest_containers.py::test_a_log_is_read_by_what_it_holds_not_by_its_name"
CONFIG_UNKNOWN = "tests/test_config.py::test_an_unknown_key_names_the_key_it_likely_is"
LOG_OR_PRODUCT = "tests/test_safety.py::test_a_log_and_a_product_given_for_each_other_say_what_they_are"
BATCH_COMPANIONS = "tests/test_batch.py::test_batch_reads_each_drives_can_and_nmea_logs_with_it"
LUA_TI_DEMO = "tests/test_ingest_dca1000_lua.py::test_ti_demo_script_reads_as_its_arguments_say"
LUA_AS_JSON = "tests/test_ingest_dca1000_lua.py::test_a_capture_configured_by_its_lua_script_reads_as_by_its_json"
LUA_NAMED = "tests/test_ingest_dca1000_lua.py::test_a_script_named_as_the_capture_is_the_one_read_beside_others"
FLAGS_BARE = "tests/test_cli.py::test_every_commands_flags_read_as_they_are_given_not_as_taking_a_value"
ROLE_UNSET = "tests/test_config.py::test_a_layer_unsets_its_bases_can_roles_with_an_empty_string"
STAMP_OUTLIER = ("tests/test_ingest_robustness.py::"
                 "test_a_stamp_far_after_both_its_neighbours_is_an_outlier_a_real_gap_is_not")
SHIFTED_SUMMARY = "tests/test_ingest_damage.py::test_mcap_shifted_summary_is_found_by_its_data_end"
UNLISTED_TOPICS = ("tests/test_ingest_damage.py::"
                   "test_rosbag2_topics_metadata_yaml_does_not_list_are_read_from_the_storage")
MF4_DAMAGE = "tests/test_ingest_canlog.py::test_a_real_mf4_damaged_inside_its_records_keeps_the_frames_around_it"
MF4_PASTED = "tests/test_ingest_canlog.py::test_records_pasted_from_elsewhere_in_an_mf4_are_not_read_twice"
MF4_SORTED = "tests/test_ingest_canlog.py::test_a_finalised_mf4_damaged_in_its_records_keeps_every_other_frame"
MF4_STAMPS = "tests/test_ingest_canlog.py::test_an_mf4_frame_whose_stamp_falls_out_of_its_groups_order_is_left_out"
MF4_EARLY = "tests/test_ingest_canlog.py::test_a_finalised_mf4_frame_stamped_a_step_early_is_not_damage"
MF4_CLAIMS = "tests/test_ingest_canlog.py::test_a_finalised_mf4_whose_group_claims_more_records_than_it_holds"
MF4_MEND = "tests/test_ingest_canlog.py::test_an_mf4_whose_damaged_blocks_describe_empty_groups_reads_every_frame"
MF4_MEND_DATA = "tests/test_ingest_canlog.py::test_a_group_whose_data_bytes_lie_in_a_damaged_group_is_left_out_with_it"
MF4_ZEROED_STAMPS = "tests/test_ingest_canlog.py::test_zeroed_stamps_outnumbering_the_whole_ones_are_the_damage"
MF4_HALF_BUILT = ("tests/test_ingest_canlog.py::"
                  "test_a_failed_mf4_open_leaves_no_half_built_reader_to_the_garbage_collector")
BLF_DAMAGE = "tests/test_ingest_canlog.py::test_a_blf_damaged_inside_keeps_the_frames_of_every_other_container"
BLF_SIZE = "tests/test_ingest_canlog.py::test_a_blf_container_whose_size_is_damaged_is_read_to_its_streams_end"
BLF_HEADER = "tests/test_ingest_canlog.py::test_a_blf_whose_file_header_is_damaged_is_read_with_it_rebuilt"
BATCH_CTRL_C = "tests/test_batch.py::test_ctrl_c_while_the_local_clusters_workers_start_is_one_line"
BATCH_RESUME = "tests/test_batch.py::test_a_stopped_batch_keeps_what_finished_and_resume_runs_the_rest"
CONFIG_SILENT = "tests/test_config.py::test_a_config_that_would_run_wrong_without_a_word_is_refused"
CONFIG_LACKS = "tests/test_ingest_robustness.py::test_a_configs_topic_or_role_the_logs_lack_is_a_warning"
SPLIT_ORDER = "tests/test_ingest_split_order.py::test_split_can_logs_out_of_time_order_lose_nothing"
ROS1_COPIES = "tests/test_ingest_ros1_connections.py::test_a_damaged_index_copy_of_a_connection_gives_way_to_the_chunks"
MDF4_OFFSETS = "tests/test_ingest_canlog.py::test_an_mf4_frame_lost_or_written_twice_keeps_every_other_frame"
UNUSED_INPUT = "tests/test_ingest_mixed.py::test_an_input_nothing_of_which_reaches_the_drive_is_named_with_why"
RUN_CAN_LOG = "tests/test_ingest_mixed.py::test_run_reads_can_logs_beside_the_drive_log_with_ingests_options"
CONFIG_NOT_AN_OUTPUT = "tests/test_ingest_mixed.py::test_run_and_compare_never_write_over_their_config[compare]"
DRIVE_FOLDER = "tests/test_ingest_drive_folder.py::test_a_drive_folder_reads_as_its_inputs_given_one_by_one"
DRIVE_FOLDER_NESTED = "tests/test_ingest_drive_folder.py::test_a_folder_inside_a_drive_folder_gives_its_inputs"
CONFIG_TABLE_HOME = "tests/test_config.py::test_an_unknown_key_names_the_key_it_likely_is"
HDF5_DISK_FULL = ("tests/test_safety.py::"
                  "test_a_disk_that_fills_as_hdf5_writes_ends_the_command_with_its_error_not_a_crash")
HDF5_FULL_TEXT = "tests/test_safety.py::test_hdf5s_runtime_error_of_a_full_disk_is_said_as_one"
FILLS_AT = "tests/test_safety.py::test_a_disk_that_fills_at_any_stage_ends_each_command_with_one_line"
SIMULATED_FOLDER = ("tests/test_ingest_drive_folder.py::"
                    "test_a_folder_of_a_simulated_log_and_its_truth_is_that_log_and_finds_its_truth")
BATCH_FOLDER = "tests/test_batch.py::test_batch_takes_drive_folders_and_the_time_offsets_of_their_logs"
BATCH_INGEST = "tests/test_batch.py::test_batch_reads_every_drive_with_its_ingest_options"
CAN_FORWARD = "tests/test_ingest_canlog.py::test_a_can_log_whose_clock_steps_forward_is_told_from_frames_lost"
COMPARE_INGEST = "tests/test_ingest_mixed.py::test_compare_reads_can_logs_and_the_ingest_options_as_run_does"
CAPTURE_USED = "tests/test_ingest_dca1000.py::test_simulated_capture_ingests_to_the_rawframe_cube"
BOARD_TX = "tests/test_ingest_dca1000.py::test_a_capture_on_two_of_the_boards_three_tx_focuses_its_reflectors"
BOARD_CONFIG = "tests/test_config.py::test_a_board_with_more_antennas_than_the_radar_uses"
BATCH_RADAR_START = "tests/test_ingest_dca1000.py::test_batch_gives_each_drives_capture_its_own_start"
CAPTURE_SKETCH = "tests/test_ingest_dca1000_lua.py::test_the_config_sketch_of_a_capture_is_a_config_it_ingests_with"
CHECKSUM_MISFIT = ("tests/test_ingest_robustness.py::"
                   "test_a_car_with_other_checksums_than_the_rule_is_told_which_key_to_set")
INGEST_DEGRADED = "tests/test_ingest_robustness.py::test_the_drive_of_a_damaged_log_says_it_is_degraded"
PRODUCT_KIND = "tests/test_safety.py::test_a_log_and_a_product_given_for_each_other_say_what_they_are"
PARTIAL_NAMES = "tests/test_safety.py::test_files_named_as_partials_that_are_not_the_outputs_own_are_never_removed"
SIMULATE_RMTREE = "tests/test_safety.py::test_simulate_overwrite_replaces_only_a_directory_the_simulator_wrote"
PLOT_GATE = "tests/test_safety.py::test_navigate_plot_passes_the_output_gate"
REPORT_FILES = "tests/test_safety.py::test_evaluate_compare_and_run_never_replace_a_users_file_in_their_directory"
SIGTERM = "tests/test_safety.py::test_sigterm_stops_a_command_as_ctrl_c_does"
SECOND_INTERRUPT = "tests/test_safety.py::test_a_second_ctrl_c_during_the_clean_up_ends_the_command_at_once"
SWALLOWED_INTERRUPT = "tests/test_safety.py::test_an_error_that_follows_a_swallowed_ctrl_c_is_reported_as_the_interrupt"
INPUT_TWICE = "tests/test_ingest_mixed.py::test_two_recordings_of_a_stream_are_refused"
RELATIVE_RUN = ("tests/test_evaluate.py::"
                "test_a_run_of_a_relative_path_is_evaluated_against_its_truth_from_anywhere")
ATTR_CRC = "tests/test_integrity.py::test_a_flipped_byte_in_an_attribute_is_damage_not_another_value"
PIPE_IN_FOLDER = "tests/test_ingest_drive_folder.py::test_a_pipe_in_a_drive_folder_is_left_out_not_opened"
START_BOUNDS = "tests/test_ingest_dca1000.py::test_a_start_or_offset_no_clock_can_be_is_refused_naming_the_option"
CAPTURE_SHORT = "tests/test_ingest_dca1000.py::test_a_capture_cut_at_a_frames_end_says_how_many_frames_it_lacks"
EMPTY_BEAM = "tests/test_safety.py::test_an_image_no_pulse_reaches_is_refused"
FOCUS_FOLDER = "tests/test_safety.py::test_focus_makes_the_folder_of_its_output"
GROUP_SIGNAL = "tests/test_safety.py::test_a_signal_to_the_whole_process_group_stops_runs_forked_ingest_once"
SPAWNED_HANDLERS = "tests/test_safety.py::test_a_process_the_command_spawns_keeps_pythons_signal_handlers"
BATCH_RETRY = "tests/test_batch.py::test_a_drives_retry_replaces_its_first_attempts_products"
IMAGE_WARNINGS = ("tests/test_integrity.py::"
                  "test_focus_of_a_drive_damaged_in_a_radar_chunk_leaves_out_its_frames_and_says_so[1]")
RUN_NO_RADAR = "tests/test_ingest_mixed.py::test_a_run_of_a_log_without_radar_names_the_ingest_that_writes_it"
BLF_START = "tests/test_ingest_canlog.py::test_a_blf_whose_start_time_is_no_date_is_read_at_offsets_with_a_warning"
BLF_START_KEPT = "tests/test_ingest_canlog.py::test_a_blf_whose_start_time_alone_is_lost_takes_it_from_its_stop_time"
BLF_FILE_SIZE = "tests/test_ingest_canlog.py::test_a_blf_whose_file_size_is_damaged_is_told_from_one_cut_short"
MCAP_UNVERIFIED = ("tests/test_ingest_damage.py::"
                   "test_an_uncompressed_chunk_failing_its_crc_is_read_when_asked_its_damage_in_one_message")
BLF_LAST = ("tests/test_ingest_canlog.py::"
            "test_a_blf_whose_last_container_is_damaged_keeps_what_its_stream_gave_before")
TEXT_DAMAGE = "tests/test_ingest_canlog.py::test_a_text_log_damaged_in_a_line_keeps_every_other_line"
TEXT_BLOCKS = ("tests/test_ingest_canlog.py::"
               "test_an_asc_damaged_in_its_second_trigger_block_reads_on_at_that_blocks_times")
TEXT_FIRST = ("tests/test_ingest_canlog.py::"
              "test_a_text_log_whose_first_frame_line_is_damaged_reads_the_others_at_their_times")
MF4_SHIFT = "tests/test_ingest_canlog.py::test_a_real_mf4_with_bytes_added_or_lost_before_its_data_reads_its_frames"
MF4_PAST_ANY_FILE = "tests/test_ingest_canlog.py::test_links_overwritten_past_any_file_are_damage_not_a_shift"
MF4_SHIFT_NAMED = "tests/test_ingest_canlog.py::test_a_shift_moves_no_link_onto_a_block_an_intact_link_names"
MF4_SHIFT_FINALISED = ("tests/test_ingest_canlog.py::"
                       "test_a_finalised_mf4_with_bytes_added_or_lost_keeps_the_frames_they_spare")
MF4_DLC_TABLE = ("tests/test_ingest_canlog.py::"
                 "test_an_mf4_whose_dlc_table_is_damaged_reads_each_frame_with_its_own_bytes")
DLC_TABLE_JUDGED = "tests/test_ingest_canlog.py::test_a_dlc_table_is_judged_by_iso_11898_1"
MF4_UNNEEDED = "tests/test_ingest_canlog.py::test_a_damaged_block_no_record_needs_is_unlinked_and_its_groups_kept"
MF4_DG_COMMENT = "tests/test_ingest_canlog.py::test_a_data_groups_garbage_comment_link_is_unlinked"
MF4_GARBAGE_LINK = ("tests/test_ingest_canlog.py::"
                    "test_a_block_whose_descriptive_link_is_garbage_is_damaged_with_its_group")
TEXT_SKIPPED = "tests/test_ingest_canlog.py::test_a_text_log_frame_line_damaged_where_the_reader_looks_is_counted"
TEXT_LONG_DLC = "tests/test_ingest_canlog.py::test_an_ascs_classic_frame_with_a_dlc_over_8_is_read_as_8_bytes"
ODD_INPUTS = "tests/test_safety.py::test_an_input_that_is_a_pipe_a_link_loop_or_a_directory_is_one_line"
NMEA_DAMAGE = "tests/test_ingest_nmea.py::test_a_block_of_nul_bytes_in_a_capture_is_one_damage_warning_with_its_place"
MISLABELLED = ("tests/test_ingest_damage.py::"
               "test_rosbag2_storage_mislabelled_in_metadata_is_read_as_what_its_files_are")
RUN_MARKED = ("tests/test_run.py::"
              "test_a_run_stopped_after_its_ingest_is_marked_unfinished[stop0]")
SAME_ANTENNAS = "tests/test_sar_focus.py::test_a_config_whose_antennas_are_not_the_drives_is_refused"
STRICT_JSON = "tests/test_evaluate.py::test_run_writes_every_product_and_the_manifest"
COMPARE_CLI = "tests/test_evaluate.py::test_compare_cli_on_ci"
SAME_BITS = "tests/test_kernel_determinism.py::test_backprojection_is_identical_with_compiled_and_cached_kernel"
IMPOSSIBLE_ID = "tests/test_ingest_canlog.py::test_a_frame_whose_damaged_id_no_frame_can_have_is_warned_of"
SAID_BEFORE = "tests/test_ingest_damage.py::test_what_went_wrong_before_an_ingest_error_is_said_with_it"
NMEA_CUT = "tests/test_ingest_nmea.py::test_a_capture_cut_inside_its_last_sentence_says_so"
GNSS_NOISIER = "tests/test_nav_gnss_noise.py::test_only_a_receiver_noisier_than_its_table_is_reweighed"
ENTROPY = "tests/test_evaluate.py::test_entropy_and_contrast_exact"
FAR_SWATH = "tests/test_evaluate.py::test_far_swath_is_the_pixels_far_from_the_radars_track"
SE2 = "tests/test_evaluate.py::test_se2_fit_recovers_a_known_rigid_motion"
REFLECTORS = "tests/test_evaluate.py::test_reflectors_with_the_truth_trajectory_and_a_rigidly_moved_one"
PEAK_LOSS = "tests/test_evaluate.py::test_peak_loss_is_what_a_blurring_track_costs_each_reflector"
ROAD_RAYS = "tests/test_sim_kernels.py::test_a_point_over_a_reflecting_road_lobes_as_the_two_ray_model"
ROAD_REF = "tests/test_sim_kernels.py::test_beat_kernel_matches_float64_reference_by_way_of_the_road"
REFERENCE_ERROR = "tests/test_evaluate.py::test_the_error_from_the_truth_images_peak_leaves_out_that_images_own_offset"
RPE = "tests/test_nav_models.py::test_relative_pose_error_ignores_rigid_motion_and_sees_bends"
STEADY_TURN = "tests/test_sim_dynamics.py::test_steady_turn_side_slip_and_roll_match_the_linear_single_track"
SUSPENSION_STEP = "tests/test_sim_dynamics.py::test_suspension_step_response_is_the_second_order_model"
ROAD_PSD = "tests/test_sim_dynamics.py::test_road_psd_matches_iso8608"
FULL_POSE = "tests/test_sim_dynamics.py::test_full_pose_derivatives_are_consistent"
CLIMB_PITCH = "tests/test_sim_dynamics.py::test_a_body_on_a_climbing_road_pitches_nose_up_with_it"
CLOCK_FOCUS = "tests/test_sar_focus.py::test_a_stated_radar_clock_focuses_a_late_drifting_capture_where_it_was"
CLOCK_DEFINITION = "tests/test_sim_dynamics.py::test_the_radar_clocks_definition_in_hand_numbers"
TILES = "tests/test_batch.py::test_split_grid_positions_bit_identical"
MOUNTING = "tests/test_nav_frames.py::test_mounting_angles_turn_the_radar_as_the_config_says"
MCAP_RESYNC = "tests/test_ingest_damage.py::test_mcap_bad_record_length_resynchronises"
ROS1_RESYNC = "tests/test_ingest_damage.py::test_ros1_damaged_chunk_header_resynchronises"
ROS1_RECORDS = ("tests/test_ingest_damage.py::test_ros1_uncompressed_message_with_a_damaged_length_costs_only_that_"
                "message")
ROS1_CHUNK_LENGTH = "tests/test_ingest_damage.py::test_ros1_chunk_whose_data_length_is_off_but_fits_costs_nothing"
ROS1_TIME_COPIES = "tests/test_ingest_damage.py::test_ros1_message_time_damaged_in_one_copy_is_read_at_the_other"
ROS1_SIZE_FIELD = ("tests/test_ingest_damage.py::test_ros1_uncompressed_chunk_whose_size_field_is_off_is_read_by_its_"
                   "data_length")
ROS1_RUN_ON = ("tests/test_ingest_damage.py::test_ros1_uncompressed_message_whose_length_runs_over_an_indexed_record_"
               "costs_nothing")
ROS1_RUN_ON_CONNECTION = ("tests/test_ingest_damage.py::test_ros1_uncompressed_message_whose_length_runs_over_a_"
                          "connection_record_costs_nothing")
_QUIRKS = "tests/test_ingest_quirks.py::"
_DCA = "tests/test_ingest_dca1000.py::"
QUIRK_OUTLIVING = _QUIRKS + "test_gnss_outliving_the_imus_and_can_gives_a_trajectory_its_readers_take"
QUIRK_MUX = _QUIRKS + "test_a_multiplexed_dbc_message_is_decoded_or_refused_clearly"
QUIRK_SAME_ID = _QUIRKS + "test_another_message_with_the_same_number_is_not_decoded_as_the_dbcs"
QUIRK_WHEEL_SCALE = _QUIRKS + "test_wheel_speeds_a_few_per_cent_off_are_scaled_to_the_gnss_speed"
QUIRK_IMU_LATE = _QUIRKS + "test_an_imu_stamped_late_is_not_read_as_a_gnss_latency_after_the_stamps"
QUIRK_GNSS_EDGE = _QUIRKS + "test_a_gnss_latency_beyond_the_search_is_warned_of"
QUIRK_CLOCK = _QUIRKS + "test_a_stream_stamped_on_another_clock_is_warned_of"
QUIRK_NMEA_ONLY = _QUIRKS + "test_a_receiver_logged_only_as_nmea_is_navigated"
QUIRK_NMEA_CAPTURE = _QUIRKS + "test_an_nmea_capture_is_navigated_once_the_config_names_its_receiver"
NO_FRAME_INSIDE = "tests/test_sar_focus.py::test_a_trajectory_no_radar_frame_lies_inside_is_refused_for_that"
TRUTH_FIRST = "tests/test_run.py::test_a_truth_sidecar_that_is_none_is_refused_before_the_ingest"
INFO_FOLD = "tests/test_cli.py::test_info_on_a_narrow_terminal_gives_each_stream_and_type_whole"
CHOICE_MEANT = "tests/test_cli.py::test_a_misspelt_choice_is_refused_with_the_one_it_likely_meant"
SET_WHOLE = "tests/test_safety.py::test_a_set_of_products_the_block_replaced_in_part_goes_whole"
SIM_TOGETHER = "tests/test_safety.py::test_a_simulation_stopped_as_its_log_comes_into_place_puts_its_truth_there_too"
PLOT_TOGETHER = "tests/test_safety.py::test_a_trajectory_stopped_as_it_comes_into_place_brings_its_plot"
IMAGE_DISK_FULL = "tests/test_safety.py::test_a_disk_that_fills_as_the_image_is_closed_is_an_error_not_a_crash"
WORKER_SIGNALS = "tests/test_safety.py::test_a_process_the_command_spawns_keeps_pythons_signal_handlers"
PEAK_GRID_PHASE = "tests/test_sar_focus.py::test_a_reflectors_peak_does_not_move_with_where_the_5mm_samples_fall"
AF_REF = "tests/test_residual_motion.py::test_focus_history_is_the_reference_backprojection_pulse_by_pulse"
AF_INJECTED = "tests/test_residual_motion.py::test_recovers_an_injected_across_track_error"
AF_CLUTTER = "tests/test_residual_motion.py::test_refuses_distributed_clutter"
AF_OWN_NOISE = "tests/test_residual_motion.py::test_each_point_is_weighed_by_its_own_noise"
AF_CLIMB = "tests/test_residual_motion.py::test_a_track_that_climbs_the_data_do_not_is_no_scale"
AF_WINDOWS = "tests/test_residual_motion.py::test_gathered_histories_are_each_pulses_own_range_profile"
AF_GUARD = "tests/test_residual_motion.py::test_a_correction_that_does_not_sharpen_the_points_is_not_applied"
FAST = "tests/test_fast_motion.py::test_recovers_a_fast_across_track_error_from_many_scatterers"
FAST_NORMALS = "tests/test_fast_motion.py::test_the_histories_banded_normal_equations_are_the_sparse_products"
FAST_HALVES = "tests/test_fast_motion.py::test_halves_that_measure_opposite_motions_correct_nothing"
FAST_MIRROR = "tests/test_fast_motion.py::test_steps_where_a_walls_mirror_image_aliases_onto_the_point_are_left_out"
PASS_BRAKING = "tests/test_pass_ranges.py::test_a_slip_gains_error_is_fitted_from_the_points_seen_through_a_braking"
PASS_BLOCK_CONFIG = "tests/test_pass_ranges.py::test_the_config_sets_the_passes_block"
GAINS_UNDONE = "tests/test_channel_gains.py::test_gains_normalise_and_their_correction_undoes_them"
ENGINES_SLIP = ("tests/test_nav_sarmin.py::"
                "test_compiled_filter_equals_the_filterpy_reference[gauss_markov-0.05-True-False]")
ATTITUDE = "tests/test_nav_models.py::test_attitude_from_the_imu_is_the_full_vehicles"
TILT = "tests/test_nav_models.py::test_tilt_offsets_are_the_rigid_rotation"
RADAR_SLOPE = "tests/test_nav_models.py::test_radar_slope_from_the_gnss_climb_and_the_imu_is_the_full_vehicles"
SLIP_DRIFT = ("tests/test_nav_models.py::"
              "test_a_slip_gains_error_drifts_the_track_by_its_gain_times_the_change_of_half_the_speed_squared")


@dataclass(frozen=True)
class Mutation:
    name: str
    area: str
    edits: tuple[tuple[str, str, str], ...]  #: (file under autosar_cli/, exact snippet, replacement)
    tests: tuple[str, ...]  #: pytest node ids, run in this order with -x


def _m(name: str, area: str, file: str, old: str, new: str, *tests: str) -> Mutation:
    return Mutation(name, area, ((file, old, new),), tests)


MUTATIONS: list[Mutation] = [
    # --- kernels: phase sign, interpolation, window edges
    _m("bp-phase-conjugated", "kernel", "sar/backprojection.py",
       "return s_re * cs + s_im * sn, s_im * cs - s_re * sn", "return s_re * cs - s_im * sn, s_im * cs + s_re * sn",
       RAD8),
    _m("bp-interpolation-nearest-lower-bin", "kernel", "sar/backprojection.py",
       "return a_re + fr * (b_re - a_re), a_im + fr * (b_im - a_im)", "return a_re, a_im", RAD8),
    _m("bp-interpolation-weights-swapped", "kernel", "sar/backprojection.py",
       "    fr = fi - np.floor(fi)\n", "    fr = 1 - (fi - np.floor(fi))\n", RAD8),
    _m("stripmap-beam-twice-as-wide", "kernel", "sar/stripmap.py",
       "return wavelength_m / (4.0 * resolution_m)", "return wavelength_m / (2.0 * resolution_m)", RAD8),
    _m("stripmap-window-edge-past-zero-doppler", "kernel", "sar/stripmap.py",
       "vel[m, 0], vel[m, 1], vel[m, 2]) < -s_max:", "vel[m, 0], vel[m, 1], vel[m, 2]) < 0.0:", RAD8),
    _m("range-compression-rvp-sign", "kernel", "sar/range_compression.py",
       "+ np.pi * f**2 / slope_hz_per_s)", "- np.pi * f**2 / slope_hz_per_s)", RANGE_REF),
    _m("range-compression-window-centre", "kernel", "sar/range_compression.py",
       "np.pi * k * (n - 1) / nfft", "np.pi * k * n / nfft", RANGE_REF),
    _m("sim-beat-phase-conjugated", "kernel", "sim/echo.py",
       "p_im[i] = a * s_im[i] + b * s_re[i]", "p_im[i] = -(a * s_im[i] + b * s_re[i])", BEAT_REF),
    _m("sim-beat-rvp-sign", "kernel", "sim/echo.py",
       "cycles_mid = f0 * tau_m + slope * tau_m * t_mid - 0.5 * slope * tau_m * tau_m",
       "cycles_mid = f0 * tau_m + slope * tau_m * t_mid + 0.5 * slope * tau_m * tau_m", BEAT_REF),
    # the road's paths: the image mirrored about the road, a trihedral's one-bounce paths, the two-bounce Gamma^2
    _m("sim-road-image-not-mirrored", "kernel", "sim/echo.py",
       "ptz = 2.0 * mirror_z[m] - pz if path[i] & 1 else pz", "ptz = 2.0 * mirror_z[m] + pz if path[i] & 1 else pz",
       ROAD_RAYS),
    _m("sim-trihedral-returns-one-bounce-paths", "kernel", "sim/echo.py",
       "cross_gain = np.where(above & ~retro, road_reflection, 0.0)",
       "cross_gain = np.where(above, road_reflection, 0.0)", ROAD_RAYS),
    _m("sim-two-bounce-path-with-gamma", "kernel", "sim/echo.py",
       "bounce_gain = np.where(above, road_reflection ** 2, 0.0)",
       "bounce_gain = np.where(above, road_reflection, 0.0)", ROAD_REF),
    # --- the simulator's full vehicle, the model the processor is checked against (sim/dynamics.py, sim/road.py)
    _m("sim-rear-slip-angle-sign", "simulator", "sim/dynamics.py",
       "alpha_r = math.atan((b * r - vy) / veff)", "alpha_r = math.atan((vy - b * r) / veff)", STEADY_TURN),
    _m("sim-body-rolls-into-the-turn", "simulator", "sim/dynamics.py",
       "roll = suspension_response(dt, roll_road, k_roll * accel_y,",
       "roll = suspension_response(dt, roll_road, -k_roll * accel_y,", STEADY_TURN),
    _m("sim-suspension-base-undamped", "simulator", "sim/dynamics.py",
       "for num, u in (([2.0 * damping_ratio * w, w * w], base_input)", "for num, u in (([w * w], base_input)",
       SUSPENSION_STEP),
    _m("sim-road-rougher-at-short-wavelengths", "simulator", "sim/road.py",
       "(np.asarray(n) / ISO8608_N0) ** (-ISO8608_WAVINESS)",
       "(np.asarray(n) / ISO8608_N0) ** (-ISO8608_WAVINESS + 0.5)", ROAD_PSD),
    _m("sim-road-pitch-sign", "simulator", "sim/dynamics.py",
       "pitch_road = -(0.5 * (h[:, 0] + h[:, 1]) - 0.5 * (h[:, 2] + h[:, 3])) / wheelbase",
       "pitch_road = (0.5 * (h[:, 0] + h[:, 1]) - 0.5 * (h[:, 2] + h[:, 3])) / wheelbase", CLIMB_PITCH),
    _m("sim-euler-rates-yaw-into-pitch-sign", "simulator", "sim/dynamics.py",
       "dth * cf + dpsi * ct * sf", "dth * cf - dpsi * ct * sf", FULL_POSE),
    # --- channel mapping and phase centres
    _m("rx-order-reversed", "channels", "sar/focus.py",
       "np.stack([pc.rx[:, t, r] for t, r in pairs])", "np.stack([pc.rx[:, t, 3 - r] for t, r in pairs])", RAD8),
    _m("eight-channels-use-tx1", "channels", "sar/focus.py",
       "return [(t, r) for t in (0, 2) for r in range(n_rx)]", "return [(t, r) for t in (0, 1) for r in range(n_rx)]",
       TWELVE),
    _m("eight-channels-lose-one", "channels", "sar/focus.py",
       "return [(t, r) for t in (0, 2) for r in range(n_rx)]",
       "return [(t, r) for t in (0, 2) for r in range(n_rx)][1:]", RAD8),
    _m("antenna-layout-mirrored", "channels", "nav/trajectory.py",
       "lever + np.asarray(r.rx_positions_m) @ rot.T", "lever + np.asarray(r.rx_positions_m) @ rot", RAD8),
    _m("radar-pitched-up-where-stated-down", "channels", "nav/frames.py",
       "rot_y(np.deg2rad(pitch_deg))", "rot_y(np.deg2rad(-pitch_deg))", MOUNTING),
    _m("radar-mounting-angles-applied-x-y-z", "channels", "nav/frames.py",
       "return rot_z(np.deg2rad(yaw_deg)) @ rot_y(np.deg2rad(pitch_deg)) @ rot_x(np.deg2rad(roll_deg))",
       "return rot_x(np.deg2rad(roll_deg)) @ rot_y(np.deg2rad(pitch_deg)) @ rot_z(np.deg2rad(yaw_deg))", MOUNTING),
    _m("radar-lever-arm-1-percent-long", "channels", "nav/trajectory.py",
       "    lever = np.asarray(r.mounting.lever_arm_m, dtype=np.float64)\n    return lever",
       "    lever = 1.01 * np.asarray(r.mounting.lever_arm_m, dtype=np.float64)\n    return lever", RAD8),
    # --- the range axis
    _m("range-shift-one-bin", "range axis", "sar/focus.py",
       "range0_m=0.0, bin_m=bin_m", "range0_m=bin_m, bin_m=bin_m", RAD8),
    _m("range-shift-half-bin", "range axis", "sar/focus.py",
       "range0_m=0.0, bin_m=bin_m", "range0_m=0.5 * bin_m, bin_m=bin_m", RAD8),
    _m("speed-of-light-rounded", "range axis", "config.py",
       "SPEED_OF_LIGHT = 299_792_458.0", "SPEED_OF_LIGHT = 3.0e8", RAD8, RANGE_REF),
    _m("range-bin-size-of-the-unpadded-fft", "range axis", "sar/focus.py",
       "SPEED_OF_LIGHT * fs / (n_bins * slope),", "SPEED_OF_LIGHT * fs / ((n_bins - 4) * slope),",
       RAD8),
    # --- SAR-MIN: updates and models
    Mutation("steering-dropped-in-both-engines", "sar-min", (
        ("nav/sarmin_kernel.py", "if kind == ng + 1 and x[V] < steer_min_speed:", "if kind == ng + 1:"),
        ("nav/sarmin.py", "if ukf.x[m.V] < nav.steering_min_speed_mps:", "if True:")), (SENSORS,)),
    _m("kernel-rear-wheels-swapped", "sar-min", "nav/sarmin_kernel.py",
       "zsig[i, 2] = (forward - w * tr / 2) * (1.0", "zsig[i, 2] = (forward + w * tr / 2) * (1.0", ENGINES),
    _m("kernel-gnss-velocity-lever-sign", "sar-min", "nav/sarmin_kernel.py",
       "by = -sig[i, V] * np.sin(alpha) + sig[i, OMEGA] * lx", "by = -sig[i, V] * np.sin(alpha) - sig[i, OMEGA] * lx",
       ENGINES),
    _m("model-gyro-bias-sign", "sar-min", "nav/models.py",
       "return (X[:, OMEGA] + X[:, bias_index])[:, None]", "return (X[:, OMEGA] - X[:, bias_index])[:, None]",
       ENGINES),
    _m("setup-gnss-lever-not-moved-to-the-rear-axle", "sar-min", "nav/sarmin.py",
       "return lx + config.vehicle.cog_to_rear_axle_m, ly", "return lx, ly", NAV_CI),
    _m("setup-wheel-update-skipped", "sar-min", "nav/sarmin_kernel.py",
       "k_dim = 4 if kind == ng else (1 if kind == ng + 1 else 2)",
       "k_dim = 4 if kind == ng else (1 if kind == ng + 1 else 2)\n"
       "            if kind == ng:\n                continue",
       SENSORS),
    _m("wheel-lag-one-move-per-row", "sar-min", "nav/wheel_speeds.py",
       "        v = np.abs(z[:, w])\n", "        v = np.abs(z).mean(axis=1)\n", WHEEL_LAG),
    _m("wheel-lag-moved-forward", "sar-min", "nav/wheel_speeds.py",
       "        described = t - delay\n", "        described = t + delay\n", WHEEL_LAG),
    # --- the slow motion from the points' passes
    _m("pass-ranges-doppler-shift-added", "autofocus", "sar/pass_ranges.py",
       "    offset = offset - doppler\n", "    offset = offset + doppler\n", PASS_DOPPLER),
    _m("pass-ranges-stretch-left-in-the-shape", "autofocus", "sar/pass_ranges.py",
       "along - stretch * (s_nodes - s_centre), across", "along, across", PASS_INJECTED),
    _m("pass-block-not-from-the-config", "autofocus", "sar/pass_ranges.py",
       "return cls(block_s=config.processing.autofocus_pass_block_s)", "return cls()", PASS_BLOCK_CONFIG),
    _m("pass-block-config-not-bounded", "autofocus", "config.py",
       "if not 0.0 < p.autofocus_pass_block_s <= 1.0:", "if p.autofocus_pass_block_s < 0.0:", PASS_BLOCK_CONFIG),
    # --- the residual-motion autofocus: its model, fits and refusals (sar/residual_motion.py, sar/history_kernel.py)
    _m("af-history-carrier-conjugated", "autofocus", "sar/history_kernel.py",
       "phase = -2.0 * math.pi * (turns - math.floor(turns))", "phase = 2.0 * math.pi * (turns - math.floor(turns))",
       AF_REF),
    _m("af-history-nearest-lower-bin", "autofocus", "sar/history_kernel.py",
       "s_re = float(s0.real) + f * (float(s1.real) - float(s0.real))", "s_re = float(s0.real)", AF_REF),
    _m("af-point-shift-sign", "autofocus", "sar/residual_motion.py",
       "vals.append(-kappa * du[:, k])", "vals.append(kappa * du[:, k])", AF_INJECTED),
    _m("af-scale-lever-sign", "autofocus", "sar/residual_motion.py",
       'vals.append(kappa * (np.einsum("nk,nk->n", smp.los[b_idx], smp.lever[b_idx])',
       'vals.append(-kappa * (np.einsum("nk,nk->n", smp.los[b_idx], smp.lever[b_idx])', AF_CLIMB, AF_INJECTED),
    _m("af-correction-interpolation-swapped", "autofocus", "sar/residual_motion.py",
       "moved = at_nodes[f_node] * (1.0 - f_frac) + at_nodes[f_node + 1] * f_frac + x[-1] * scale_lever",
       "moved = at_nodes[f_node] * f_frac + at_nodes[f_node + 1] * (1.0 - f_frac) + x[-1] * scale_lever",
       AF_INJECTED),
    _m("af-phase-residual-limit-ignored", "autofocus", "sar/residual_motion.py",
       "bad = used & (phase_rms > opts.max_phase_rms_rad)", "bad = used & (phase_rms > 100.0)", AF_CLUTTER),
    _m("af-coherence-check-skipped", "autofocus", "sar/residual_motion.py",
       "if coherence_after <= coherence_before:", "if False:", AF_GUARD),
    _m("af-one-noise-for-all-points", "autofocus", "sar/residual_motion.py",
       "opts.min_steps_own_noise if point_noise else None", "None", AF_OWN_NOISE),
    _m("af-window-off-its-range", "autofocus", "sar/phase_history.py",
       "b0 = np.floor(path / bin_m).astype(np.int64) - (w // 2 - 1)",
       "b0 = np.floor(path / bin_m).astype(np.int64) - (w // 2 + 1)", AF_WINDOWS, AF_INJECTED),
    _m("af-beam-twice-as-wide", "autofocus", "sar/phase_history.py",
       '& (np.abs(np.einsum("fpk,fk->fp", d, along)) <= sin_half_beam * horiz)',
       '& (np.abs(np.einsum("fpk,fk->fp", d, along)) <= 2.0 * sin_half_beam * horiz)', AF_WINDOWS, AF_INJECTED),
    _m("channel-gains-applied-not-undone", "autofocus", "sar/channel_gains.py",
       "return (1.0 / normalised(np.array([g[t, r] for t, r in pairs]))).astype(np.complex64)",
       "return normalised(np.array([g[t, r] for t, r in pairs])).astype(np.complex64)", GAINS_UNDONE),
    _m("pass-ranges-slip-drift-of-braking-as-driving", "autofocus", "nav/wheel_speeds.py",
       "ramps[1:, 1] = np.cumsum(v_mid * np.minimum(dv, 0.0))", "ramps[1:, 1] = np.cumsum(v_mid * np.maximum(dv, 0.0))",
       SLIP_DRIFT, PASS_BRAKING),
    # --- the fast motion from many scatterers (sar/fast_motion.py, sar/step_normals.py)
    _m("fast-correction-sign", "autofocus", "sar/fast_motion.py",
       "MotionCorrection(nodes_ns, (-gain * sosfiltfilt(sos, whole.motion))",
       "MotionCorrection(nodes_ns, (gain * sosfiltfilt(sos, whole.motion))", FAST),
    _m("fast-mirror-alias-kept", "autofocus", "sar/fast_motion.py",
       "ok = (alias > opts.alias_hz) | (np.abs(mirror) < opts.alias_hz / 4)", "ok = alias == alias", FAST_MIRROR),
    _m("fast-halves-disagreeing-applied", "autofocus", "sar/fast_motion.py",
       "    if not r > 0.0:\n", "    if False:\n", FAST_HALVES),
    _m("fast-normals-weight-squared", "autofocus", "sar/step_normals.py",
       "band[k, j] += w * blocks[ptr[s] + p, k]", "band[k, j] += w * w * blocks[ptr[s] + p, k]", FAST_NORMALS),
    # --- SAR-MIN's vehicle terms: rear slip, attitude, the radar's tilt and slope
    _m("nav-rear-slip-angle-sign", "sar-min", "nav/sarmin_kernel.py",
       "alpha = slip * sig[i, V] * sig[i, OMEGA]", "alpha = -slip * sig[i, V] * sig[i, OMEGA]", ENGINES_SLIP),
    _m("attitude-roll-from-the-accelerometers-sign", "sar-min", "nav/attitude.py",
       "roll_g = np.arcsin(np.clip((f[:, 1] - a_y)", "roll_g = np.arcsin(np.clip((a_y - f[:, 1])", ATTITUDE),
    _m("tilt-offsets-roll-sign", "sar-min", "nav/attitude.py",
       "dy = cr * ly - sr * lz - ly", "dy = cr * ly + sr * lz - ly", TILT),
    _m("radar-slope-tilt-from-the-antenna-to-the-radar-reversed", "sar-min", "nav/navigate.py",
       "above = tilt_heights(att.roll, att.pitch, radar) - tilt_heights(att.roll, att.pitch, antenna)",
       "above = tilt_heights(att.roll, att.pitch, antenna) - tilt_heights(att.roll, att.pitch, radar)", RADAR_SLOPE),
    # --- the measuring stick: entropy, far swath, alignment, reflector errors, peak loss, RPE (evaluate/)
    _m("entropy-in-bits", "evaluation", "evaluate/image_quality.py",
       "return float(-np.sum(p * np.log(p)))", "return float(-np.sum(p * np.log2(p)))", ENTROPY),
    _m("far-swath-the-near-pixels", "evaluation", "evaluate/evaluation.py",
       "far = dist >= min_range_m", "far = dist < min_range_m", FAR_SWATH),
    _m("alignment-rotated-the-other-way", "evaluation", "evaluate/alignment.py",
       "angle = math.atan2(cross, dot) if", "angle = math.atan2(-cross, dot) if", SE2),
    _m("reflector-error-against-the-true-position", "evaluation", "evaluate/reflectors.py",
       "        d = peak - xy\n", "        d = peak - true[:2]\n", REFLECTORS),
    _m("reference-error-with-the-references-offset-added", "evaluation", "evaluate/reflectors.py",
       "reference_error_m=float(np.hypot(*(d - ref_offset[name])))",
       "reference_error_m=float(np.hypot(*(d + ref_offset[name])))", REFERENCE_ERROR),
    _m("peak-loss-sign", "evaluation", "evaluate/reflectors.py",
       "peak_loss_db=None if ref is None else ref - m.peak_db", "peak_loss_db=None if ref is None else m.peak_db - ref",
       PEAK_LOSS),
    _m("rpe-across-sign", "evaluation", "nav/trajectory.py",
       "return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)",
       "return np.stack([c * d[:, 0] + s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=1)", RPE),
    # --- the radar's clock and the image's tiles (store/drive.py, sar/tiles.py)
    _m("radar-clock-stated-but-not-applied", "focus", "store/drive.py",
       "        if not late_s and not drift_ppm:\n            return self\n",
       "        if True:\n            return self\n", CLOCK_FOCUS),
    _m("radar-clock-late-taken-as-early", "focus", "store/drive.py",
       "    out = stamps - int(round(late_s * 1e9))\n", "    out = stamps + int(round(late_s * 1e9))\n",
       CLOCK_DEFINITION),
    _m("tiles-start-a-column-late", "focus", "sar/tiles.py",
       "        first = grid.pixel_enu(0, c0)\n", "        first = grid.pixel_enu(0, c0 + 1)\n", TILES),
    # --- geodesy and GeoTIFF georeferencing
    _m("geodesy-east-north-swapped", "geodesy", "types.py",
       "pymap3d.enu2geodetic(p[..., 0], p[..., 1], p[..., 2]", "pymap3d.enu2geodetic(p[..., 1], p[..., 0], p[..., 2]",
       GEOTIFF),
    _m("geodesy-utm-zone-off-by-one", "geodesy", "types.py",
       "int((self.lon_deg + 180.0) // 6.0) + 1, 60)", "int((self.lon_deg + 180.0) // 6.0) + 2, 60)", GEOTIFF),
    _m("geodesy-antimeridian-is-zone-61", "geodesy", "types.py",
       "zone = min(int((self.lon_deg + 180.0) // 6.0) + 1, 60)", "zone = int((self.lon_deg + 180.0) // 6.0) + 1",
       UTM_ANYWHERE),
    _m("geotiff-half-pixel-shift", "geotiff", "store/image.py",
       "grid.pixel_enu(v - 0.5, u - 0.5)", "grid.pixel_enu(v, u)", GEOTIFF),
    _m("quicklook-pooled-cell-at-its-first-pixel", "geotiff", "store/quicklook.py",
       "extent = ((c.start * pool - 0.5) * pixel_m, (c.stop * pool - 0.5) * pixel_m,",
       "extent = ((c.start - 0.5) * pool * pixel_m, (c.stop - 0.5) * pool * pixel_m,", QUICKLOOK_POOLED),
    # --- SAR-MIN's fits to the drive: understeer, standstill, the GNSS's and the CAN bus's latency, the GNSS noise
    _m("understeer-against-the-bicycle-sign", "sar-min", "nav/understeer.py",
       "r = z - np.arctan(wheelbase_m * w / v)", "r = z + np.arctan(wheelbase_m * w / v)", UNDERSTEER),
    _m("standstill-from-one-wheel", "sar-min", "nav/wheel_speeds.py",
       "stopped = np.all(wheels.z == 0.0, axis=1)", "stopped = wheels.z[:, 0] == 0.0", STANDSTILL),
    _m("gnss-latency-moved-later", "sar-min", "nav/gnss_latency.py",
       "return None if m is None else replace(m, t=m.t - change_s)",
       "return None if m is None else replace(m, t=m.t + change_s)", GNSS_DELAYED),
    _m("can-latency-moved-later", "sar-min", "nav/can_latency.py",
       "return None if meas is None else replace(meas, t=meas.t - delay_s)",
       "return None if meas is None else replace(meas, t=meas.t + delay_s)", CAN_LATE),
    _m("gnss-noise-of-a-quieter-receiver-taken", "sar-min", "nav/gnss_noise.py",
       "    if fit.ratio < MIN_RATIO:\n", "    if fit.ratio < 0.0:\n", GNSS_NOISIER),
    # --- a real radar's raw data: TI DCA1000 captures (ingest/dca1000.py)
    _m("dca1000-2-lane-samples-not-interleaved", "radar", "ingest/dca1000.py",
       "out.reshape(-1)[...] = _swap_middle_pair(values).reshape(-1)", "out.reshape(-1)[...] = values.reshape(-1)",
       DCA_LAYOUTS),
    _m("dca1000-4-lane-i-and-q-swapped", "radar", "ingest/dca1000.py",
       "out[...] = v[:, :, :, lanes].transpose(0, 3, 1, 2)",
       "out[...] = v[:, :, ::-1][:, :, :, lanes].transpose(0, 3, 1, 2)", DCA_LAYOUTS),
    _m("dca1000-chirps-not-regrouped-by-tx", "radar", "ingest/dca1000.py",
       "return chirps if order == list(range(p.num_tx)) else chirps[:, order]", "return chirps", DCA_LAYOUTS),
    _m("dca1000-narrow-samples-not-sign-extended", "radar", "ingest/dca1000.py",
       "values[values >= 1 << (p.adc_bits - 1)] -= np.int16(1 << p.adc_bits)", "pass", DCA_NARROW),
    _m("dca1000-zero-fill-taken-for-echoes", "radar", "ingest/dca1000_packets.py",
       "ZERO_RUN_VALUES = 256", "ZERO_RUN_VALUES = 1 << 30", DCA_ZEROS),
    # --- inputs are sacred, damage is named: output guards, checksums, integrity checks, degraded runs
    _m("overwrite-replaces-a-foreign-file", "safety", "store/outputs.py",
       "    if not (ours and path.is_file() and not path.is_symlink()) and not is_autosar_product(path):\n",
       "    if False:\n", FOREIGN),
    _m("output-may-be-its-input", "safety", "store/outputs.py",
       'raise OutputError(f"{path}: is an input of this command; choose another output")', "pass", OWN_INPUT),
    _m("output-may-lie-inside-its-input", "safety", "store/outputs.py",
       "        if source in target.parents:\n", "        if False:\n", INSIDE_INPUT),
    _m("stale-partials-left-behind", "safety", "store/outputs.py",
       "        remove_stale_partials(path, keep=[Path(p) for p in inputs])\n", "        pass\n", STALE),
    _m("degraded-run-reported-as-complete", "safety", "cli.py",
       "return f\" [yellow]degraded[/] ({n} warning{'' if n == 1 else 's'} above{kept})\" if warnings else \"\"",
       'return ""', DEGRADED),
    _m("mcap-damage-ends-the-read", "integrity", "ingest/mcap_source.py",
       "nxt = _next_record(self.path, resync_from + 1, total)", "nxt = None", MCAP_RESYNC),
    _m("ros1-damaged-chunk-ends-the-read", "integrity", "ingest/ros1_chunks.py",
       "    at = start\n    while (hit := buf.find(_CHUNK_OP, at)) >= 0:\n",
       "    at = start\n    while False and (hit := buf.find(_CHUNK_OP, at)) >= 0:\n", ROS1_RESYNC),
    _m("ros1-record-damage-ends-the-chunk", "integrity", "ingest/ros1_chunks.py",
       "            nxt = _next_record(data, last if last is not None else at + 1, connections, cut)",
       "            nxt = None", ROS1_RECORDS),
    _m("ros1-message-length-trusted", "integrity", "ingest/ros1_chunks.py",
       "nxt is not None and nxt < at or not _header_like(data, at, nxt))", "False)", ROS1_RECORDS),
    _m("ros1-index-read-on-unchained-records", "integrity", "ingest/rosbag_source.py",
       "            broken = self._chunk_break(reader)", "            broken = None", ROS1_RECORDS),
    _m("ros1-chunk-data-length-trusted", "integrity", "ingest/ros1_chunks.py",
       "    return stream[1], stream[2]\n\n\ndef _uncompressed_read_by",
       "    return None\n\n\ndef _uncompressed_read_by", ROS1_CHUNK_LENGTH),
    _m("ros1-uncompressed-size-field-trusted", "integrity", "ingest/ros1_chunks.py",
       "    length_holds = dend <= len(buf) and _record_follows(buf, dend)", "    length_holds = False",
       ROS1_SIZE_FIELD),
    _m("ros1-record-time-trusted-over-the-index", "integrity", "ingest/rosbag_source.py",
       "                    if said is not None and said[:2] != (msg.conn_id, msg.t_ns):",
       "                    if False:", ROS1_TIME_COPIES),
    _m("ros1-message-run-on-over-an-indexed-record", "integrity", "ingest/ros1_chunks.py",
       "            if op == OP_MSG_DATA and starts:", "            if False:", ROS1_RUN_ON),
    _m("ros1-message-run-on-over-a-connection-record", "integrity", "ingest/ros1_chunks.py",
       "                iend = _connection_cut(data, at, inner, istart, iend, connections, report, where)\n",
       "                pass\n", ROS1_RUN_ON_CONNECTION),
    _m("ros1-index-read-over-a-connection-record", "integrity", "ingest/ros1_chunks.py",
       "        inside = _connection_within(buf, at + 8 + hlen, at + 8 + hlen + dlen, {})",
       "        inside = None", ROS1_RUN_ON_CONNECTION),
    _m("ros1-message-run-into-a-connection-record-left-out", "integrity", "ingest/ros1_chunks.py",
       "            if pending is not None and nxt is not None and pending[2] <= nxt < at and _declared(",
       "            if False and nxt is not None and pending[2] <= nxt < at and _declared(",
       ROS1_RUN_ON_CONNECTION),
    _m("misspelt-choice-without-its-likely-meaning", "inputs", "cli.py",
       "near = difflib.get_close_matches(given.lower(), choices, n=1, cutoff=0.6)", "near = []", CHOICE_MEANT),
    _m("sensor-key-of-another-kind-ignored", "inputs", "config.py",
       '        if cls is SensorConfig and value.get("kind") in REQUIRED_ERROR_TABLES:', "        if False:",
       CONFIG_SILENT),
    _m("overwritten-set-left-part-old", "safety", "store/outputs.py",
       "            if replaced or (product == manifest or before[product] is None):",
       "            if product == manifest or before[product] is None:", SET_WHOLE),
    _m("former-manifest-kept-while-replacing", "safety", "store/outputs.py",
       "            os.replace(manifest, aside)\n", "            pass\n", SET_WHOLE),
    _m("simulated-log-and-truth-placed-apart", "safety", "sim/simulate.py",
       "            with interrupts_held():  # the log, its capture and its truth",
       "            with contextlib.nullcontext():  # the log, its capture and its truth", SIM_TOGETHER),
    _m("trajectory-and-plot-placed-apart", "safety", "cli.py",
       "            with interrupts_held():  # the trajectory and its plot",
       "            with open(os.devnull):  # the trajectory and its plot", PLOT_TOGETHER),
    _m("abandoned-image-flushed-on-a-full-disk", "safety", "store/image.py",
       '            os.truncate(self._tmp["h5"], 0)', "            pass", IMAGE_DISK_FULL),
    _m("workers-die-of-the-groups-sigterm", "safety", "__init__.py",
       "            signal.signal(signal.SIGTERM, signal.SIG_IGN)\n", "            pass\n", WORKER_SIGNALS),
    _m("reflector-peak-between-5mm-samples", "evaluation", "evaluate/point_target.py",
       "    di, dj = lobe_top(fmag * fmag, int(fi), int(fj)) or refine_peak(fmag * fmag, int(fi), int(fj))",
       "    di, dj = refine_peak(fmag * fmag, int(fi), int(fj))", PEAK_GRID_PHASE),
    _m("radar-cube-without-checksums", "integrity", "store/drive.py",
       "dtype=np.int16, fletcher32=True,", "dtype=np.int16, fletcher32=False,", CUBE_CRC),
    _m("trajectory-without-checksums", "integrity", "store/trajectory.py",
       "f.create_dataset(name, data=getattr(traj, name), fletcher32=True)",
       "f.create_dataset(name, data=getattr(traj, name), fletcher32=False)", TRACK_CRC),
    _m("another-recordings-track-focused", "integrity", "sar/focus.py",
       'if n := radar.unmatched(frames["frame_index"], frames["crc32"]):', "if n := 0:", OTHER_RECORDING),
    _m("can-frame-with-a-bad-checksum-kept", "integrity", "ingest/decoders.py",
       'if int(raw["CHECKSUM"]) != giorgio_checksum(m.frame_id, data):', "if False:", CAN_FAULTS),
    _m("nmea-sentence-with-a-bad-checksum-kept", "integrity", "ingest/nmea.py",
       "if checksum.strip().upper() != calc_checksum(content):", "if False:", NMEA_BAD),
    # --- ingest scaling
    _m("can-degrees-as-gradians", "ingest", "candb.py",
       '"deg": (math.pi / 180.0, "rad"),', '"deg": (math.pi / 200.0, "rad"),', CAN_UNITS),
    _m("nmea-minutes-as-hundredths", "ingest", "ingest/nmea.py",
       "value = deg + minutes / 60.0", "value = deg + minutes / 100.0", NMEA_SIM),
    _m("can-dbc-scale-and-offset-not-applied", "ingest", "ingest/decoders.py",
       "values = m.decode(data, decode_choices=False, scaling=lay.unscaled_integrity)",
       "values = m.decode(data, decode_choices=False, scaling=False)", CAN_SI),
    # --- drives logged on other sensors: an IMU's mounting and gravity, fixes alone, a config's layers
    _m("imu-mounting-transposed", "inputs", "nav/frames.py",
       "sum(r[i, j] * v[:, j] for j in range(3) if r[i, j] != 0.0)",
       "sum(r[j, i] * v[:, j] for j in range(3) if r[j, i] != 0.0)", TURNED),
    _m("imu-turned-by-gravity-accepted", "inputs", "nav/inputs.py",
       "if tilt > MAX_GRAVITY_TILT_DEG:", "if tilt > 180.0:", GRAVITY_TILT),
    _m("imu-in-g-accepted", "inputs", "nav/inputs.py",
       "if not GRAVITY_RANGE_MPS2[0] <= magnitude <= GRAVITY_RANGE_MPS2[1]:", "if False:", IN_G),
    _m("imu-levelling-roll-sign", "inputs", "nav/frames.py",
       "math.degrees(math.atan2(gy, gz))", "math.degrees(math.atan2(-gy, gz))", LEVELLING),
    _m("fixes-first-move-reversed", "inputs", "nav/sarmin.py",
       "step = pos.z[k, :2] - pos.z[j, :2]", "step = pos.z[j, :2] - pos.z[k, :2]", FIRST_MOVE, FIXES_ALONE),
    _m("fix-velocity-one-sided", "inputs", "nav/baselines.py",
       "a, b = np.clip(i - n, 0, len(t) - 1), np.clip(i + n, 0, len(t) - 1)",
       "a, b = i, np.clip(i + n, 0, len(t) - 1)", FIX_VELOCITY),
    _m("gate-warns-of-the-gnss-alone", "inputs", "nav/navigate.py",
       "if total < MIN_GATED or gated <= MAX_GATED_SHARE * total:",
       'if total < MIN_GATED or gated <= MAX_GATED_SHARE * total or not stream.startswith("gnss_"):', GATED_GYRO),
    _m("config-unknown-key-said-without-the-key-it-likely-is", "inputs", "config.py",
       "f\"{_suggestion(unknown[0], sorted(names), value[unknown[0]])}\")", "\"\")", CONFIG_UNKNOWN),
    _m("dca1000-word-bits-unchecked", "radar", "ingest/dca1000_params.py",
       "if fmt is not None and DCA_FORMAT_BITS.get(_int_or_none(fmt)) != params.adc_bits:",
       "if False:", DCA_CLI_CONFIG),
    _m("dca1000-cli-config-beside-an-sdk-cfg-unread", "radar", "ingest/dca1000_params.py",
       'if not p.name.endswith(".mmwave.json")', 'if p.name.endswith(".setup.json")', DCA_CLI_CONFIG),
    _m("batch-time-offset-given-to-every-drive", "inputs", "batch.py",
       "time_offsets={Path(p): offsets[p] for p in sorted(own) if p in offsets}",
       "time_offsets={Path(p): s for p, s in offsets.items()}", BATCH_COMPANIONS),
    _m("batch-drive-read-without-its-can-log", "inputs", "batch.py",
       "can_logs=inputs[\"can\"],", "can_logs=[],", BATCH_COMPANIONS),
    _m("lua-profile-slope-read-from-the-rx-gain", "radar", "ingest/dca1000_lua.py",
       "slope_hz_per_s=_scaled(str(prof[11]), 12)", "slope_hz_per_s=_scaled(str(prof[17]), 12)", LUA_TI_DEMO),
    _m("lua-variables-left-unresolved", "radar", "ingest/dca1000_lua.py",
       "if number is None and len(values.get(arg, ())) == 1:", "if False:", LUA_AS_JSON),
    _m("lua-block-comment-read-as-code", "radar", "ingest/dca1000_lua.py",
       'text = _BLOCK_COMMENT.sub(lambda m: "\\n" * m.group(0).count("\\n"),',
       'text = _BLOCK_COMMENT.sub(lambda m: m.group(0),', LUA_TI_DEMO),
    _m("capture-parameter-file-named-yet-its-folder-searched", "radar", "ingest/dca1000.py",
       "params = [named] if named else next(", "params = [named] if named and False else next(", LUA_NAMED),
    _m("help-shows-every-flag-beside-a-type", "inputs", "cli.py",
       'param.metavar = ""', "param.metavar = None", FLAGS_BARE),
    _m("config-base-table-replaced-whole", "inputs", "config.py",
       "out[key] = _merged(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value",
       "out[key] = value", CONFIG_BASE),
    _m("can-receiver-course-east-and-north-swapped", "inputs", "nav/inputs.py",
       "enu = np.stack([speed * np.sin(c), speed * np.cos(c), np.full(len(c), np.nan)], axis=1)",
       "enu = np.stack([speed * np.cos(c), speed * np.sin(c), np.full(len(c), np.nan)], axis=1)", CAN_VELOCITY),
    _m("can-role-of-a-twice-named-message-guessed", "inputs", "ingest/pipeline.py",
       "if len(found) == 1:", "if found:", TWICE_NAMED),
    _m("missing-hdf5-read-as-not-hdf5", "inputs", "store/hdf5_read.py",
       "if isinstance(exc, FileNotFoundError) or not Path(path).exists():", "if False:", CUT_SHORT),
    # --- damaged and odd inputs (the fault campaign's realfiles and path classes)
    _m("empty-role-kept", "inputs", "config.py", 'if ref != ""}}', "}}", ROLE_UNSET),
    _m("stamp-outlier-taken", "ingest", "ingest/series.py",
       "            if t < ahead[0] - self.max_step_ns:", "            if False:", STAMP_OUTLIER),
    _m("shifted-mcap-summary-not-sought", "ingest", "ingest/mcap_source.py",
       "            found = _summary_by_its_data_end(self.path)", "            found = None", SHIFTED_SUMMARY),
    _m("rosbag2-unlisted-topics-left", "ingest", "ingest/rosbag_source.py",
       "        unlisted = self._storage_topics() - set(self.declared) - set(seen)", "        unlisted = set()",
       UNLISTED_TOPICS),
    _m("mf4-damage-margin-none", "ingest", "ingest/mdf4_blocks.py",
       "_DAMAGE_MARGIN = 2", "_DAMAGE_MARGIN = 0", MF4_DAMAGE),
    _m("pipe-taken-as-a-file", "inputs", "store/outputs.py",
       "if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):", "if False:", ODD_INPUTS),
    _m("nmea-damaged-lines-uncounted", "ingest", "ingest/nmea.py",
       "                if _damage(decoder.skipped) > damaged:", "                if False:", NMEA_DAMAGE),
    _m("rosbag2-storage-label-trusted", "ingest", "ingest/rosbag_source.py",
       "    mislabelled = found is not None and found != storage", "    mislabelled = False", MISLABELLED),
    _m("impossible-can-id-taken-as-unknown", "ingest", "ingest/decoders.py",
       "            if frame.frame_id > (_MAX_EXTENDED_ID if frame.is_extended else _MAX_STANDARD_ID):",
       "            if False:", IMPOSSIBLE_ID),
    _m("warnings-before-an-ingest-error-dropped", "ingest", "ingest/pipeline.py",
       "        exc.warnings = list(dict.fromkeys((job.warnings if job is not None else []) + exc.warnings))",
       "        exc.warnings = []", SAID_BEFORE),
    _m("nmea-cut-last-line-unwarned", "ingest", "ingest/pipeline.py",
       """        if reader.skipped["cut off by the file's end"]:""", "        if False:", NMEA_CUT),
    _m("mf4-offsets-after-a-hole-unmended", "ingest", "ingest/mdf4_blocks.py",
       """piece[at:at + size] = (offset - moved).to_bytes(size, "little")""",
       """piece[at:at + size] = offset.to_bytes(size, "little")""", MF4_DAMAGE),
    _m("mf4-resync-offsets-unbounded", "ingest", "ingest/mdf4_blocks.py",
       "if run is not None and all(0 <= run[1][v] - kept.get(v, 0) <= run[0] - kept_to for v in run[1]):",
       "if run is not None:", MF4_PASTED),
    _m("mf4-resync-times-unchecked", "ingest", "ingest/mdf4_blocks.py",
       "                if now < time:", "                if False:", MF4_PASTED),
    _m("mf4-sorted-neighbours-kept", "ingest", "ingest/mdf4_sorted.py",
       "    bad[:-1] |= broken[1:]\n    bad[1:] |= broken[:-1]\n", "", MF4_SORTED),
    _m("mf4-sorted-order-unchecked", "ingest", "ingest/mdf4_sorted.py",
       "    if n < 2 or not in_order and np.mean(follows & leads) < _IN_ORDER:", "    if True:", MF4_SORTED),
    _m("mf4-sorted-times-unchecked", "ingest", "ingest/mdf4_sorted.py",
       "                bad |= out_of_order(", "                bad |= 0 * out_of_order(", MF4_SORTED),
    _m("mf4-stamps-unchecked", "ingest", "ingest/mdf4_blocks.py",
       "            flagged[mine] = out_of_order(", "            flagged[mine] = 0 * out_of_order(", MF4_STAMPS),
    _m("mf4-sorted-time-slack-none", "ingest", "ingest/mdf4_sorted.py", "_STEP_SLACK = 10", "_STEP_SLACK = 0",
       MF4_EARLY),
    _m("mf4-sorted-claimed-count-kept", "ingest", "ingest/mdf4_sorted.py",
       """        struct.pack_into("<Q", dest_bytes, cg_data + 8, len(rows))\n""", "", MF4_CLAIMS),
    _m("mf4-block-damage-not-mended", "ingest", "ingest/mdf4_blocks.py",
       "    mend = mend_chains(buf)", "    mend = None", MF4_MEND),
    _m("mf4-broken-chain-not-sought-on", "ingest", "ingest/mdf4_mend.py",
       """            more = _found(buf, b"##CG", cgs, _CG_LINKS, [r for r in data if r is not None])""",
       "            more = []", MF4_MEND),
    _m("mf4-group-kept-whose-data-bytes-are-left-out", "ingest", "ingest/mdf4_mend.py",
       "out = [cg for cg, groups in reached.items() if all(g in reached for g in groups)]",
       "out = list(reached)", MF4_MEND_DATA),
    _m("mf4-equal-stamps-make-a-run", "ingest", "ingest/mdf4_sorted.py",
       "        k = bisect.bisect_left(tails, t)", "        k = bisect.bisect_right(tails, t)", MF4_ZEROED_STAMPS),
    _m("mf4-half-built-reader-left-to-the-collector", "ingest", "ingest/canlog.py",
       "            _release_half_built(exc)\n", "", MF4_HALF_BUILT),
    _m("blf-damage-not-sought", "ingest", "ingest/canlog.py",
       'else blf_damage(path) if suffix == ".blf"', 'else None if suffix == ".blf"', BLF_DAMAGE),
    _m("blf-object-broken-by-a-hole-kept", "ingest", "ingest/blf_damage.py",
       'pending, first = b"", _first_object(inner)', "first = 0", BLF_DAMAGE),
    _m("blf-stated-size-trusted", "ingest", "ingest/blf_damage.py",
       "    if pos + size <= len(buf) and len(inflate.unused_data) <= _PADDING:", "    if pos + size <= len(buf):",
       BLF_SIZE),
    _m("blf-header-size-trusted", "ingest", "ingest/blf_damage.py",
       "    if signature == b\"LOGG\" and (size == _HEADER_SIZE or (",
       "    if signature == b\"LOGG\" and (True or (", BLF_HEADER),
    _m("blf-start-time-no-date-unsaid", "ingest", "ingest/canlog.py",
       "        return reader.start_timestamp == 0\n", "        return False\n", BLF_START),
    _m("blf-start-time-not-taken-from-its-stop-time", "ingest", "ingest/blf_damage.py",
       "        if _start_lost(buf) and (last := _whole(buf)[1]) is not None:\n",
       "        if False and (last := _whole(buf)[1]) is not None:\n", BLF_START_KEPT),
    _m("blf-start-time-taken-from-a-file-that-lost-its-end", "ingest", "ingest/blf_damage.py",
       "    if why is not None or pending or total != struct.unpack_from(\"<Q\", buf, _UNCOMPRESSED_SIZE_AT)[0]:\n",
       "    if why is not None or pending:\n", BLF_START, BLF_FILE_SIZE),
    _m("blf-damaged-file-size-read-as-a-cut", "ingest", "ingest/canlog.py",
       "            if holds_every_container(read):", "            if False:", BLF_FILE_SIZE),
    _m("mcap-unverified-message-its-index-does-not-list-kept", "integrity", "ingest/mcap_source.py",
       "                    if listed is not None and (channel_id, log_time, at) not in listed:\n",
       "                    if False:\n", MCAP_UNVERIFIED),
    _m("mcap-unverified-chunk-left-out-when-asked", "integrity", "ingest/mcap_source.py",
       "            if not self.keep_unverified:\n", "            if True:\n", MCAP_UNVERIFIED),
    _m("log-named-as-a-can-log-read-by-its-name", "ingest", "ingest/inputs.py",
       "    if begins_as_a_container(path):  # an MCAP", "    if False:  # an MCAP", BY_WHAT_IT_HOLDS),
    _m("input-adding-nothing-unsaid", "ingest", "ingest/pipeline.py",
       "        job.warnings += job.unused + job.misnamed_topics()\n",
       "        job.warnings += job.misnamed_topics()\n", UNUSED_INPUT),
    _m("can-log-among-a-runs-logs-read-as-a-container", "ingest", "ingest/inputs.py",
       "            sorted_.by_kind[classify_input(p)].append(p)\n", "            sorted_.by_kind[\"log\"].append(p)\n",
       RUN_CAN_LOG),
    _m("drive-folder-read-as-a-bag", "ingest", "ingest/inputs.py",
       "    if path.is_dir() and drive_folder(path) is not None:", "    if False:", DRIVE_FOLDER),
    _m("drive-folder-inner-folders-unread", "ingest", "ingest/inputs.py",
       "elif depth < MAX_DEPTH and (inner :=", "elif False and (inner :=", DRIVE_FOLDER_NESTED),
    _m("drive-folder-left-out-unsaid", "ingest", "ingest/inputs.py",
       "            sorted_.warnings.append(said)", "            pass", DRIVE_FOLDER),
    _m("config-table-of-another-tables-keys-unnamed", "config", "config.py",
       "    if isinstance(value, dict) and value:\n", "    if False:\n", CONFIG_TABLE_HOME),
    _m("drive-h5-given-without-o-said-missing-alone", "ingest", "ingest/inputs.py",
       "if path.suffix.lower() in (\".h5\", \".hdf5\") and not path.exists() and not path.is_symlink():",
       "if False:", "tests/test_cli.py::test_a_drive_h5_given_without_o_is_said_to_want_it"),
    _m("missing-h5-log-told-to-give-the-o-it-gave", "ingest", "cli.py",
       "if getattr(ctx.get_parameter_source(\"output\"), \"name\", \"\") == \"DEFAULT\":", "if True:",
       "tests/test_cli.py::test_a_missing_h5_log_beside_an_output_given_is_not_said_to_want_o"),
    _m("pixel-in-cm-unsaid-where-the-track-is-shorter", "focus", "sar/grid.py",
       "if pixel_m >= 1 else \"\"", "if False else \"\"", "tests/test_sar_backprojection.py::test_grids"),
    _m("disk-full-hdf5-left-to-crash-the-shutdown", "safety", "cli.py",
       "    if _state[\"disk_filled\"]:\n", "    if False:\n", HDF5_DISK_FULL),
    _m("disk-full-hdf5-runtime-error-said-as-its-text", "safety", "disk_full.py",
       " or HDF5_DISK_FULL in str(exc)", "", HDF5_FULL_TEXT),
    _m("disk-full-h5py-destructor-tracebacks-shown", "safety", "cli.py",
       "with nullcontext() if _state[\"debug\"] else reports_held():", "with nullcontext():",
       f"{FILLS_AT}[navigate]"),
    _m("disk-full-libtiff-lines-printed", "safety", "store/image.py",
       "\n            route_libtiff_messages()  #", "\n            None  #", f"{FILLS_AT}[focus-tiles]"),
    _m("disk-full-geotiff-write-said-in-rasterios-words", "safety", "store/image.py",
       "except rasterio.errors.RasterioIOError as exc:", "except ZeroDivisionError as exc:", f"{FILLS_AT}[focus-tif]"),
    _m("disk-full-batch-worker-tracebacks-shown-later", "safety", "batch.py",
       "        drop_disk_full_reports()  #", "        pass  #", f"{FILLS_AT}[batch]"),
    _m("disk-full-run-json-error-in-hdf5s-words", "safety", "run.py",
       "        if is_disk_full(exc):  # as the command says it", "        if False:  # as the command says it",
       f"{FILLS_AT}[run-navigate]"),
    _m("drive-folder-of-a-simulated-log-read-as-a-bag", "ingest", "ingest/inputs.py",
       "or p.with_name(p.name + \".truth.h5\").is_file()]", "or False]", SIMULATED_FOLDER),
    _m("batch-drive-folder-time-offset-refused", "inputs", "batch.py",
       "folder.inputs[\"nmea\"]] if folder else []", "folder.inputs[\"nmea\"]] if False else []", BATCH_FOLDER),
    _m("batch-drive-read-without-the-ingest-options", "batch", "batch.py",
       "            ingest_options=ingest_options, can_logs",
       "            ingest_options=None, can_logs",
       BATCH_INGEST),
    _m("compare-config-not-an-input", "evaluate", "evaluate/compare.py",
       "*config.files, *ingest_options.files()]\n", "*ingest_options.files()]\n", CONFIG_NOT_AN_OUTPUT),
    _m("compare-ingests-without-its-options", "evaluate", "evaluate/compare.py",
       'partial_hint=chain_hint("a comparison"), **ingest_options.ingest_kwargs())',
       'partial_hint=chain_hint("a comparison"))', COMPARE_INGEST),
    _m("focus-takes-the-configs-antennas-not-the-drives", "radar", "sar/focus.py",
       "        config = replace(config, radar=r.using_channels(tx, rx))", "        pass", BOARD_TX),
    _m("board-rows-in-use-ignored", "radar", "config.py",
       "        return tuple(board[k] for k in self.tx_in_use)", "        return board", BOARD_CONFIG),
    _m("batch-radar-start-unused", "batch", "batch.py",
       "start_ns=start_ns)) if start_ns is not None else o)", "start_ns=start_ns)) if False else o)",
       BATCH_RADAR_START),
    _m("capture-sketch-without-the-boards-antennas", "radar", "config_sketch.py",
       '        if getattr(r, f"{kind}_channels") is not None or tuple(used) != tuple(range(len(getattr(',
       '        if False and tuple(used) != tuple(range(len(getattr(',
       CAPTURE_SKETCH),
    _m("checksum-rule-misfit-unsaid", "ingest", "ingest/pipeline.py",
       "    if not failed or failed < can.decoded:", "    if True:", CHECKSUM_MISFIT),
    _m("ingest-of-damaged-input-not-marked-degraded", "safety", "cli.py",
       '        if degraded := _degraded(report.warnings, "its /provenance report"):',
       '        if degraded := _degraded([], "its /provenance report"):', INGEST_DEGRADED),
    _m("product-of-another-kind-unnamed", "safety", "store/outputs.py",
       '    what = f"it is {got[0]} autosar wrote" if got else', '    what = f"" if got else', PRODUCT_KIND),
    _m("stale-partials-of-any-name-removed", "safety", "store/atomic.py",
       "        if not own.match(p.name) or p.is_dir()", "        if not PARTIAL_NAME.search(p.name) or p.is_dir()",
       PARTIAL_NAMES),
    _m("simulate-overwrite-removes-a-run-directory", "safety", "store/outputs.py",
       "    if others := sorted(p.name for p in path.iterdir() if not (p.is_file() and _SIMULATED_FILES",
       "    if False and (others := 0):  # ", SIMULATE_RMTREE),
    _m("navigate-plot-past-the-output-gate", "safety", "cli.py",
       "            _prepare_output(output.with_suffix(\".png\"), overwrite, [drive, truth, cfg.source], ours=plotted)",
       "            pass", PLOT_GATE),
    _m("evaluate-replaces-the-users-report", "safety", "evaluate/report.py",
       "    check_products(out, PRODUCTS, read, overwrite=overwrite, manifest=METRICS)", "    pass", REPORT_FILES),
    _m("run-replaces-products-without-overwrite", "safety", "run.py",
       "overwrite=overwrite or (replace_unfinished and unfinished)",
       "overwrite=True or (replace_unfinished and unfinished)",
       REPORT_FILES),
    _m("sigterm-ends-the-command-at-once", "safety", "__init__.py",
       "        signal.signal(signal.SIGTERM, exit_interrupted)\n", "        pass\n", SIGTERM),
    _m("second-interrupt-waits-for-the-clean-up", "safety", "cli.py",
       "        exit_interrupted(signum, frame)\n    _state[\"stopped_by\"] = signum",
       "        pass\n    _state[\"stopped_by\"] = signum", SECOND_INTERRUPT),
    _m("error-after-a-swallowed-interrupt-reported-as-itself", "safety", "cli.py",
       "        if (signum := _state[\"stopped_by\"]) is not None and not _state[\"debug\"]:",
       "        if (signum := None) is not None and not _state[\"debug\"]:", SWALLOWED_INTERRUPT),
    _m("input-given-twice-read-twice", "inputs", "ingest/inputs.py",
       "        if (first := seen.setdefault((st.st_dev, st.st_ino), path)) is not path:",
       "        if (first := seen.setdefault((st.st_dev, st.st_ino), path)) is not path and False:", INPUT_TWICE),
    _m("inputs-recorded-as-given", "safety", "run.py",
       '{"path": os.path.abspath(p), "size_bytes"', '{"path": str(p), "size_bytes"', RELATIVE_RUN),
    _m("image-warnings-not-evaluated", "safety", "evaluate/evaluation.py",
       "    ev.input_warnings += [str(w) for w in image.provenance", "    _ = [str(w) for w in image.provenance",
       IMAGE_WARNINGS),
    _m("forked-ingest-keeps-the-commands-handlers", "safety", "run.py",
       "    stopped = _stop_once()\n", "    stopped = (lambda: None)\n", GROUP_SIGNAL),
    _m("spawned-worker-takes-the-commands-quick-exit", "safety", "__init__.py",
       '    if mp is not None and mp.current_process().name != "MainProcess":', "    if False:",
       SPAWNED_HANDLERS),
    _m("batch-retry-refuses-its-first-attempt", "batch", "batch.py",
       "            replace_unfinished=True))", "            replace_unfinished=False))",
       BATCH_RETRY),
    _m("attribute-checksum-unchecked", "integrity", "store/attr_checksum.py",
       "    if stored != found:\n", "    if False:\n", ATTR_CRC),
    _m("drive-folder-opens-a-pipe", "inputs", "ingest/inputs.py",
       "        if not (entry.is_dir() or entry.is_file()):", "        if False:", PIPE_IN_FOLDER),
    _m("radar-start-in-seconds-taken-for-ns", "radar", "ingest/pipeline.py",
       "    if not _EARLIEST_START_NS <= ns < 2**63:", "    if not -2**63 <= ns < 2**63:", START_BOUNDS),
    _m("capture-short-of-its-frames-unsaid", "radar", "ingest/dca1000.py",
       "        if p.num_frames and self.num_frames < p.num_frames:", "        if False:", CAPTURE_SHORT),
    _m("empty-beam-writes-a-zero-image", "sar", "sar/focus.py",
       "    if n == 0:\n        where = ", "    if n < 0:\n        where = ", EMPTY_BEAM),
    _m("focus-output-folder-not-made", "safety", "cli.py",
       "        _state[\"undo_on_failure\"].append(make_directories(output.parent))  # as ingest and navigate",
       "        pass  # as ingest and navigate", FOCUS_FOLDER),
    _m("capture-said-to-add-nothing-to-the-drive", "ingest", "ingest/pipeline.py",
       'rows = read if kind == "radar" else', 'rows = 0 if kind == "radar" else', CAPTURE_USED),
    _m("failed-command-leaves-the-empty-directories-it-made", "safety", "store/outputs.py",
       "                directory.rmdir()", "                pass", RUN_NO_RADAR, LOG_OR_PRODUCT),
    _m("product-given-as-a-log-said-to-be-an-unknown-container", "safety", "ingest/sources.py",
       "if (product := what_autosar_wrote(path)) is not None:", "if (product := None) is not None:", LOG_OR_PRODUCT),
    _m("log-given-as-a-product-said-to-be-no-hdf5-file", "safety", "cli.py",
       "if begins_as_a_container(path) or (path.is_dir() and is_log_directory(path) and not is_autosar_product(path)):",
       "if False:",
       LOG_OR_PRODUCT),
    _m("blf-stream-end-unchecked", "ingest", "ingest/blf_damage.py",
       "    if method != _DEFLATED or not inflate.eof or len(inner) != inflated_size:",
       "    if method != _DEFLATED:", BLF_LAST),
    _m("text-line-a-reader-fails-on-ends-the-read", "ingest", "ingest/canlog.py",
       "                if feed is not None and feed.after_damage():", "                if False:", TEXT_DAMAGE),
    _m("text-header-not-read-again", "ingest", "ingest/text_lines.py",
       "        self._replay = [*self.header, *([self._last_mark] if self._last_mark is not None else [])]\n", "",
       TEXT_DAMAGE),
    _m("text-line-of-nul-bytes-handed-on", "ingest", "ingest/text_lines.py",
       "            if held_back and self.line in held_back:", "            if False:", TEXT_DAMAGE),
    _m("text-damaged-first-frame-line-ends-the-read", "ingest", "ingest/text_lines.py",
       "            if self._before_first is None:\n                return False", "            return False",
       TEXT_FIRST),
    _m("text-asc-trigger-block-not-read-again", "ingest", "ingest/canlog.py",
       """    marks = ("Begin Trigger", "begin trigger") if suffix == ".asc" else ()""", "    marks = ()", TEXT_BLOCKS),
    _m("text-frame-short-of-its-bytes-kept", "ingest", "ingest/canlog.py",
       "                whole = len(msg.data) == msg.dlc or _holds_its_bytes(msg, feed.last_line())",
       "                whole = True", TEXT_DAMAGE),
    _m("mdf4-shift-not-tried", "ingest", "ingest/mdf4_blocks.py", "    shift = shifted_links(buf)\n",
       "    shift = None\n", MF4_SHIFT),
    _m("mdf4-dlc-table-not-judged", "ingest", "ingest/mdf4_blocks.py",
       "            tables = damaged_length_tables(buf, found)\n", "            tables = None\n", MF4_DLC_TABLE),
    _m("mdf4-dlc-table-classic-taken-for-damage", "ingest", "ingest/mdf4_dlc.py",
       "    return fd >= sum(1 for _, n in long_codes if n == CLASSIC_MAX_BYTES)", "    return True",
       DLC_TABLE_JUDGED),
    _m("mdf4-every-link-needed", "ingest", "ingest/mdf4_mend.py",
       "and k not in _NEEDED_LINKS.get(bytes(buf[holder:holder + 4]), ()):", "and False:", MF4_UNNEEDED),
    _m("mdf4-damaged-dg-comment-kept", "ingest", "ingest/mdf4_mend.py",
       "  # its comment\n            unlinked[_link(dg, 3)] = 0\n", "  # its comment\n            pass\n",
       MF4_DG_COMMENT),
    _m("mdf4-garbage-link-unlinked", "ingest", "ingest/mdf4_mend.py",
       "            if pos < len(buf) and pos % 8 == 0 and k not in", "            if k not in", MF4_GARBAGE_LINK),
    _m("mdf4-shift-leaves-blocks-off-their-boundaries", "ingest", "ingest/mdf4_shift.py", "    pad = -by % 8\n",
       "    pad = 0\n", MF4_SHIFT),
    _m("mdf4-shift-leaves-stale-links-past-the-place", "ingest", "ingest/mdf4_shift.py",
       "    moved += [(pos + HEAD.size + 8 * k, link + by) for pos, k in intact\n",
       "    moved += [(pos + HEAD.size + 8 * k, link + by) for pos, k in ()\n", MF4_SHIFT_NAMED),
    _m("mdf4-shift-trusts-a-link-to-another-kind", "ingest", "ingest/mdf4_shift.py",
       "              if link in known and _lands_right(ids, pos, k, link)}", "              if link in known}",
       MF4_SHIFT_NAMED),
    _m("mdf4-shift-lands-on-named-blocks", "ingest", "ingest/mdf4_shift.py",
       "             if link + by not in named and _lands_right(ids, owner, k, link + by)]",
       "             if _lands_right(ids, owner, k, link + by)]", MF4_SHIFT_NAMED),
    _m("mdf4-shift-in-a-finalised-file-needs-a-data-link-moved", "ingest", "ingest/mdf4_shift.py",
       " or not finalised and not any(", " or not any(", MF4_SHIFT_FINALISED),
    _m("mdf4-shift-tears-a-copied-header-in-a-finalised-file", "ingest", "ingest/mdf4_shift.py",
       "(named if finalised else starts)", "starts", MF4_SHIFT_FINALISED),
    _m("mdf4-finalised-data-block-torn-not-put-back", "ingest", "ingest/mdf4_shift.py",
       "    if finalised and torn is not None and ids[torn] in _PLAIN_DATA:",
       "    if False and torn is not None and ids[torn] in _PLAIN_DATA:", MF4_SHIFT_FINALISED),
    _m("mdf4-put-back-trusts-times-alone", "ingest", "ingest/mdf4_shift.py",
       "        odd = odd_records(put, alike, within) if alike else 0",
       "        odd = 0", MF4_SHIFT_FINALISED),
    _m("mdf4-put-back-whole-records-put-back", "ingest", "ingest/mdf4_shift.py",
       "any(by % g.size == 0 for g in alike)", "any(False for _ in alike)", MF4_SHIFT_FINALISED),
    _m("mdf4-put-back-place-records-kept", "ingest", "ingest/mdf4_shift.py",
       "            return ties[0], records_touching(", "            return ties[0], () and records_touching(",
       MF4_SHIFT_FINALISED),
    _m("mdf4-put-back-takes-the-first-of-places-apart", "ingest", "ingest/mdf4_shift.py",
       "        if step == 1 or ties[-1] - ties[0] > step:\n", "        if step == 1:\n", MF4_SHIFT_FINALISED),
    _m("mdf4-copy-keeps-the-bytes-added", "ingest", "ingest/mdf4_mend.py",
       "            src.seek(max(-count, 0), 1)\n", "", MF4_SHIFT_FINALISED),
    _m("mdf4-shift-takes-links-past-any-file", "ingest", "ingest/mdf4_shift.py",
       "            if link and (pos, k) not in intact and link < PAST_ANY_FILE:",
       "            if link and (pos, k) not in intact:", MF4_PAST_ANY_FILE),
    _m("text-skipped-frame-line-not-judged", "ingest", "ingest/text_lines.py",
       "            self._judge(self._skipped)\n            self._skipped.clear()\n",
       "            self._skipped.clear()\n", TEXT_SKIPPED),
    _m("text-doubtful-line-not-judged-again", "ingest", "ingest/text_lines.py",
       "        self.damaged += [number for number, line in doubtful",
       "        self.damaged += [number for number, line in []", TEXT_SKIPPED),
    _m("text-first-frame-shapes-forgotten", "ingest", "ingest/text_lines.py",
       "                self._first_frame_lines[length] = text\n", "                pass\n", TEXT_SKIPPED),
    _m("text-shape-slack-none", "ingest", "ingest/text_lines.py", "_SHAPE_SLACK = 2\n", "_SHAPE_SLACK = 0\n",
       TEXT_SKIPPED),
    _m("asc-classic-long-dlc-called-short", "ingest", "ingest/canlog.py",
       "    return _ASC_CLASSIC_LONG_DLC.match(line) is not None", "    return False", TEXT_LONG_DLC),
    _m("asc-damaged-dlc-token-read-as-long-dlc", "ingest", "ingest/canlog.py",
       "    return _ASC_CLASSIC_LONG_DLC.match(line) is not None", "    return True", TEXT_LONG_DLC),
    _m("radar-damaged-chunk-ends-the-read", "integrity", "store/drive.py",
       "            except DamagedFileError:\n                parts.append(np.zeros((b - a, *shape), self.raw.dtype))",
       "            except DamagedFileError:\n                raise",
       CUBE_DAMAGE),
    _m("focus-damaged-frames-not-counted", "focus", "sar/focus.py",
       "            damaged.extend(idx[~intact[idx - idx[0]]].tolist())  # zeroed: they add nothing\n", "",
       FOCUS_DAMAGE),
    _m("table-damaged-rows-end-the-read", "integrity", "store/drive.py",
       "                intact = self._table_damage(group, exc)", "                raise", TABLE_DAMAGE),
    _m("table-damaged-rows-kept-unsaid", "integrity", "store/drive.py",
       "            raise error\n        if not intact.any():", "            raise error\n        return intact\n"
       "        if not intact.any():", TABLE_DAMAGE),
    _m("can-classic-long-dlc-a-mismatch", "ingest", "ingest/decoders.py",
       "        stated = 8 if 8 < frame.dlc <= 15 and len(data) == 8 else frame.dlc", "        stated = frame.dlc",
       TEXT_LONG_DLC),
    _m("stopped-run-left-unmarked", "safety", "run.py",
       "            _mark_stopped(exc, manifest, manifest_path)\n", "", RUN_MARKED),
    _m("focus-antennas-not-checked", "focus", "sar/focus.py",
       "    _check_same_antennas(config, attrs, drive_path)\n", "", SAME_ANTENNAS),
    _m("manifest-keeps-nan", "integrity", "store/manifest.py",
       "    if isinstance(value, float) and not math.isfinite(value):\n        return None\n", "", STRICT_JSON),
    _m("verify-skips-the-runs-inside", "integrity", "cli.py",
       "        runs = sorted(p for p in path.iterdir() if (p / \"run.json\").is_file())",
       "        runs: list[Path] = []", COMPARE_CLI),
    _m("bp-compiled-in-the-calling-process", "kernel", "sar/backprojection.py",
       "    compile_in_child(_tdbp, args)  # the same machine code in every process (autosar_cli.kernel_cache)\n", "",
       SAME_BITS),
    _m("batch-workers-take-ctrl-c", "safety", "__init__.py",
       "            signal.signal(signal.SIGINT, signal.SIG_IGN)\n", "            pass\n", BATCH_CTRL_C),
    _m("batch-stop-keeps-no-record", "safety", "batch.py",
       "    except KeyboardInterrupt as exc:\n        stopped = exc\n",
       "    except KeyboardInterrupt:\n        raise\n", BATCH_RESUME),
    _m("can-role-names-unchecked", "config", "config.py", "        _known_role(role, cfg.sensors)\n", "",
       CONFIG_SILENT),
    _m("gyro-listed-twice-fused", "config", "config.py", "        if gyro in nav.gyros[:i]:", "        if False:",
       CONFIG_SILENT),
    _m("pinned-topic-typo-unsaid", "ingest", "ingest/pipeline.py",
       "            said.append(f\"{key}: {topic} is in none of the logs",
       "            said.count(f\"{key}: {topic} is in none of the logs", CONFIG_LACKS),
    _m("can-logs-read-in-the-order-given", "ingest", "ingest/pipeline.py",
       "    inputs = can_logs_in_time_order(inputs, offsets)\n", "", SPLIT_ORDER),
    _m("ros1-connection-copies-unchecked", "ingest", "ingest/rosbag_source.py",
       "            c, disagree = reconcile(", "            c, disagree = (lambda a, *_: (a, None))(", ROS1_COPIES),
    _m("mdf4-offsets-unchecked", "ingest", "ingest/mdf4_blocks.py", "        if found.holes:\n",
       "        if False:\n", MDF4_OFFSETS),
    _m("dead-reckoning-steps-onto-an-instant", "sar-min", "nav/sarmin_kernel.py",
       "        while t - t_now > max_step + step_slack:", "        while t - t_now > max_step:", QUIRK_OUTLIVING),
    _m("multiplexed-signal-read-from-every-frame", "ingest", "ingest/decoders.py",
       "float(values.get(n, math.nan)) * f", "float(values[n]) * f", QUIRK_MUX),
    _m("multiplexed-role-keeps-other-values-rows", "ingest", "store/drive.py",
       "        selected = np.isfinite(values)", "        selected = np.ones(len(values), bool)",
       QUIRK_MUX),
    _m("can-flag-fallback-for-any-id", "ingest", "ingest/decoders.py",
       "        if lay is None and frame.frame_id > _MAX_STANDARD_ID:", "        if lay is None:", QUIRK_SAME_ID),
    _m("can-second-bus-read-as-the-first", "ingest", "ingest/decoders.py",
       "            elif frame.channel != lay.bus:", "            elif False:", QUIRK_SAME_ID),
    _m("wheel-scale-not-divided", "sar-min", "nav/wheel_speeds.py",
       "    scaled = replace(inputs, wheels=Measurements(w.name, w.t, w.z / ratio, w.sigma / ratio))",
       "    scaled = inputs", QUIRK_WHEEL_SCALE),
    _m("gnss-latency-after-the-stamps-applied", "sar-min", "nav/navigate.py",
       "    elif table + fit.change_s < -GNSS_LATENCY_SIGNIFICANT * fit.std_s:", "    elif False:", QUIRK_IMU_LATE),
    _m("gnss-latency-at-the-search-edge-silent", "sar-min", "nav/navigate.py",
       "    if fit.ambiguous.startswith(EDGE) and fit.table_chi2 > EDGE_MIN_TABLE_CHI2:", "    if False:",
       QUIRK_GNSS_EDGE),
    _m("gnss-latency-edge-warned-on-a-flat-profile", "sar-min", "nav/navigate.py",
       "    if fit.ambiguous.startswith(EDGE) and fit.table_chi2 > EDGE_MIN_TABLE_CHI2:",
       "    if fit.ambiguous.startswith(EDGE):",
       "tests/test_nav_sarmin.py::test_wheel_speeds_in_another_unit_are_refused"),
    _m("stream-on-another-clock-silent", "ingest", "ingest/pipeline.py",
       "    job.warnings += _clock_disagreements(infos)", "    job.warnings += []", QUIRK_CLOCK),
    _m("auto-grid-without-frames", "focus", "sar/focus.py",
       "    if geometry.frames.size < 2:\n        raise FocusError(f\"{drive_path}: no radar frame lies inside",
       "    if False:\n        raise FocusError(f\"{drive_path}: no radar frame lies inside", NO_FRAME_INSIDE),
    _m("run-truth-checked-after-the-ingest", "inputs", "run.py",
       "    if method == \"truth\":\n        _check_truth(truth_path, given)",
       "    if False:\n        _check_truth(truth_path, given)", TRUTH_FIRST),
    _m("fix-at-0-0-taken", "ingest", "ingest/pipeline.py",
       "            elif row[0] == 0.0 and row[1] == 0.0:", "            elif False:",
       _QUIRKS + "test_fixes_at_0_0_are_not_taken_for_the_drive_s_position"),
    _m("gyro-with-its-sign-turned-kept", "sar-min", "nav/navigate.py",
       "        inputs, flipped = without_flipped_gyros(inputs)", "        flipped = []",
       _QUIRKS + "test_a_gyro_with_its_sign_turned_is_left_out_by_name"),
    _m("gyro-in-degrees-unseen", "inputs", "nav/inputs.py",
       "    return abs(scale / math.degrees(1.0) - 1.0) < DEGREES_TOLERANCE", "    return False",
       _QUIRKS + "test_a_gyro_in_degrees_per_second_is_read_as_such[gyro]"),
    _m("attitude-imu-in-degrees-said-not-read", "inputs", "nav/inputs.py",
       "            w = np.deg2rad(w)\n            out.warnings.append(", "            out.warnings.append(",
       _QUIRKS + "test_a_gyro_in_degrees_per_second_is_read_as_such[attitude_imu]"),
    _m("gravity-removed-read-as-a-unit", "inputs", "nav/inputs.py",
       "        if magnitude < GRAVITY_RANGE_MPS2[0] and np.linalg.norm(g) < GRAVITY_REMOVED_SHARE * magnitude:",
       "        if False:",
       _QUIRKS + "test_an_imu_publishing_gravity_removed_acceleration_is_named_and_its_gyros_kept"),
    _m("gravity-removed-attitude-estimated", "sar-min", "nav/navigate.py",
       "    if inputs.attitude_imu.gravity_removed:", "    if False:",
       _QUIRKS + "test_an_imu_publishing_gravity_removed_acceleration_is_named_and_its_gyros_kept"),
    _m("steering-gain-unchecked", "sar-min", "nav/navigate.py",
       "    if said := steering_gain_error(fit, veh.wheelbase_m, veh.steering_ratio):",
       "    if said := None:", _QUIRKS + "test_a_steering_that_is_not_the_cars_road_wheel_angle_is_left_out_by_name"),
    _m("steering-gain-sign-not-named", "sar-min", "nav/navigate.py",
       "    causes = [\"its sign turned\"] if fit.gain < 0 else []", "    causes = []",
       _QUIRKS + "test_a_steering_that_is_not_the_cars_road_wheel_angle_is_left_out_by_name"),
    _m("steering-gain-judged-on-a-straight-drive", "sar-min", "nav/navigate.py",
       "    if abs(fit.gain_correlation) < MIN_STEERING_CORRELATION and fit.yaw_rate_rms_radps < MIN_TURNING_RADPS:",
       "    if False:",
       "tests/test_nav_sarmin.py::test_wheel_speeds_in_another_unit_are_refused"),
    _m("steering-turned-passes-at-speed", "sar-min", "nav/navigate.py",
       "    low = max((1.0 + UNDERSTEER_RANGE[0] * v2_over_l) / STEERING_GAIN_TOLERANCE, 0.0)",
       "    low = (1.0 + UNDERSTEER_RANGE[0] * v2_over_l) / STEERING_GAIN_TOLERANCE",
       _QUIRKS + "test_a_steering_turned_on_a_fast_drive_is_named"),
    _m("role-unit-unchecked", "ingest", "ingest/pipeline.py",
       "        job.warnings += _role_unit_warnings(job, roles)", "        job.warnings += []",
       _QUIRKS + "test_a_steering_that_is_not_the_cars_road_wheel_angle_is_left_out_by_name"),
    _m("imus-late-read-as-the-can-early", "sar-min", "nav/navigate.py",
       "    if not (gnss.get(\"after_stamps\") and can.get(\"applied\") and can[\"delay_s\"] < 0",
       "    if not (False and can.get(\"applied\") and can[\"delay_s\"] < 0",
       _QUIRKS + "test_imus_stamped_late_are_moved_where_the_can_and_the_gnss_agree"),
    _m("nan-velocity-pushed", "ingest", "ingest/decoders.py",
       "    if not (math.isfinite(v.x) and math.isfinite(v.y)):\n        return None",
       "    if False:\n        return None",
       _QUIRKS + "test_a_receivers_nan_velocity_or_altitude_leaves_the_track_whole"),
    _m("nan-altitude-kept", "sar-min", "nav/inputs.py",
       "    fix, no_altitude = with_altitudes(fix, streams.fix_stream)", "    no_altitude = \"\"",
       _QUIRKS + "test_a_receivers_nan_velocity_or_altitude_leaves_the_track_whole"),
    _m("unfixed-velocities-kept", "sar-min", "nav/inputs.py",
       "    unfixed = nearest > reach", "    unfixed = nearest < 0",
       _QUIRKS + "test_velocities_where_the_receiver_gives_no_fix_are_left_out"),
    _m("ned-velocity-read-as-enu", "sar-min", "nav/inputs.py",
       "    if swapped < FRAME_FIT_ANGLE_DEG:", "    if False:",
       _QUIRKS + "test_a_gnss_velocity_in_another_frame_than_enu_is_named"),
    _m("dca-second-recording-read-on", "ingest", "ingest/dca1000_packets.py",
       "        k = _restart(start, data_bytes)\n", "        k = None\n",
       _DCA + "test_a_second_recording_appended_to_the_first_is_left_out_by_name"),
    _m("dca-short-first-recording-read-as-repeats", "ingest", "ingest/dca1000_packets.py",
       "        if short is not None:\n            k = short\n", "        if False:\n            k = short\n",
       _DCA + "test_a_second_recording_after_a_first_of_fewer_than_64_packets_is_left_out_by_name"),
    _m("dca-triggers-not-one-per-frame-silent", "ingest", "ingest/radar_block.py",
       "    if len(stamps) > 1 and len(stamps) != n:", "    if False:",
       _DCA + "test_triggers_that_are_not_one_per_frame_are_said"),
    _m("dca-trigger-count-unsaid-with-radar-start", "ingest", "ingest/radar_block.py",
       "    if len(stamps) > 1 and len(stamps) != n:",
       "    if start_ns is None and len(stamps) > 1 and len(stamps) != n:",
       _DCA + "test_a_loop_count_off_by_two_is_said_against_the_triggers"),
    _m("dca-loop-count-against-triggers-unnamed", "ingest", "ingest/radar_block.py",
       "        other = \"\" if loops is None or", "        other = \"\" if True or",
       _DCA + "test_a_loop_count_off_by_two_is_said_against_the_triggers"),
    _m("dca-word-bits-unchecked", "ingest", "ingest/dca1000.py",
       "        self._check_word_bits()", "        pass",
       _DCA + "test_adc_words_of_other_bits_than_the_parameters_give_are_refused"),
    _m("dca-two-captures-in-one-folder", "ingest", "ingest/dca1000.py",
       "        if others:\n            raise CaptureError(f\"{path}: adc_data.bin and",
       "        if False:\n            raise CaptureError(f\"{path}: adc_data.bin and",
       _DCA + "test_a_folder_holding_adc_data_and_another_captures_files_is_refused"),
    _m("geodetic-role-read-as-an-angle", "ingest", "ingest/pipeline.py",
       "                              geodetic={(m, sig) for role, ref in config.can.roles.items()",
       "                              geodetic={(m, sig) for role, ref in {}.items()",
       _QUIRKS + "test_a_latitude_role_keeps_its_degrees_whatever_its_signals_name"),
    _m("dca-quiet-capture-taken-for-narrow-words", "ingest", "ingest/dca1000.py",
       "                and bool(np.any(values >= 3 << (bits - 2)))):", "                and True):",
       _DCA + "test_a_quiet_capture_with_a_dc_offset_reads"),
    _m("info-capture-problem-hidden", "inputs", "cli.py",
       "            if (problem := capture_problem(path)) is not None:",
       "            if (problem := None) is not None:",
       _DCA + "test_a_capture_folder_not_read_as_one_says_why"),
    _m("dca-stray-bin-beside-a-series", "ingest", "ingest/dca1000.py",
       "        if others := [b.name for b in sorted(folder.glob(\"*.bin\")) if b not in series]:",
       "        if others := []:", _DCA + "test_a_capture_folder_not_read_as_one_says_why"),
    _m("ins-receiver-velocity-unchecked", "inputs", "nav/ins.py",
       "                     rel(vel[\"t_ns\"], gnss_cfg.latency_s), velocity,",
       "                     rel(vel[\"t_ns\"], gnss_cfg.latency_s), vel[\"velocity_enu\"],",
       _QUIRKS + "test_the_ins_baselines_receiver_in_ned_is_read_as_such"),
    _m("channels-incoherent-unchecked", "focus", "sar/focus.py",
       "    if loss is None or loss <= MAX_CHANNEL_LOSS_DB:\n        return None", "    if True:\n        return None",
       "tests/test_sar_focus.py::test_a_config_that_misplaces_the_antennas_is_warned_of"),
    _m("info-names-cut-short", "inputs", "cli.py",
       "Table(Column(\"stream\", overflow=\"fold\"), Column(\"type\", overflow=\"fold\"),",
       "Table(Column(\"stream\"), Column(\"type\"),", INFO_FOLD),
    _m("nmea-epoch-counted-twice", "inputs", "nav/inputs.py",
       "    keep[np.flatnonzero(timed)[np.unique(t_fix[timed], return_index=True)[1]]] = True",
       "    keep[:] = True", QUIRK_NMEA_ONLY),
    _m("nmea-dead-reckoned-fix-taken", "inputs", "nav/inputs.py",
       "    unmeasured = np.isin(gga[\"quality\"], NMEA_UNMEASURED_QUALITIES)",
       "    unmeasured = np.isin(gga[\"quality\"], ())", QUIRK_NMEA_ONLY),
    _m("ins-nmea-velocity-up-nan", "inputs", "nav/ins.py",
       "            given = np.isfinite(ins.gnss_vel[vi])", "            given = np.ones(3, dtype=bool)",
       QUIRK_NMEA_ONLY),
    _m("nmea-receiver-not-read", "inputs", "nav/inputs.py",
       "    if \"nmea_fix\" in g or (\"nmea_velocity\" in g and \"latitude_deg\" in g[\"nmea_velocity\"]):",
       "    if False:", QUIRK_NMEA_ONLY),
    _m("sketch-capture-renamed", "inputs", "config_sketch.py",
       "    captures = set(drive.nmea_captures())", "    captures: set[str] = set()",
       QUIRK_NMEA_CAPTURE),
    _m("sketch-new-sensor-without-kind", "inputs", "config_sketch.py",
       "    if name in config.sensors:\n        return [], []", "    if True:\n        return [], []",
       QUIRK_NMEA_CAPTURE),
    _m("drive-folder-ros1-bag-unread", "inputs", "ingest/inputs.py",
       "or len(kinds) > 1 or not_storage or", "or len(kinds) > 1 or",
       "tests/test_ingest_drive_folder.py::"
       "test_a_ros1_bag_in_a_folder_is_read_not_left_out_of_a_bag_the_folder_is_taken_for"),
    _m("radar-flag-log-read-as-parameters", "inputs", "ingest/inputs.py",
       "    if kind == \"radar\" and path.is_file() and begins_as_a_container(path):",
       "    if False:", "tests/test_cli.py::test_a_log_given_as_the_radar_capture_is_named_for_what_it_is"),
    _m("dbc-given-as-log-unnamed", "inputs", "ingest/sources.py",
       "    if path.suffix.lower() == \".dbc\":", "    if False:",
       "tests/test_cli.py::test_a_dbc_or_an_unknown_file_given_as_a_log_says_what_is_read"),
    _m("current-directory-truth-name-repr", "inputs", "store/outputs.py",
       "    log = Path(os.path.abspath(log))\n    return log.with_name(log.name + \".truth.h5\") if log.name else",
       "    return log.with_name(log.name + \".truth.h5\")\n"
       "    return log.with_name(log.name + \".truth.h5\") if log.name else",
       "tests/test_cli.py::test_the_current_directory_given_as_a_product_is_named_not_a_python_repr"),
    _m("nmea-still-velocity-left-out", "inputs", "nav/inputs.py",
       "    course = np.where(speed == 0.0, 0.0, course)", "    course = course",
       _QUIRKS + "test_a_receiver_standing_still_with_no_course_reads_a_zero_velocity"),
    _m("sar-min-without-gyros-unsaid", "inputs", "nav/navigate.py",
       "        if not inputs.gyros:  # the baselines need none", "        if False:  # the baselines need none",
       _QUIRKS + "test_a_drive_of_gnss_alone_has_its_gnss_and_none_tracks"),
    _m("sketch-rate-of-one-fix-zero", "inputs", "config_sketch.py",
       "    if rate > 0:\n        return \"rate_hz\", rate, \"measured\"",
       "    if True:\n        return \"rate_hz\", rate, \"measured\"",
       "tests/test_nav_realdata.py::test_the_config_sketch_of_a_real_nmea_capture_is_a_config"),
    _m("baseline-reason-names-no-drive", "inputs", "nav/navigate.py",
       "        except NavInputError as exc:  # the baselines' reasons name no drive\n"
       "            raise NavInputError(f\"{drive_path}: {exc}\") from None",
       "        except NavInputError as exc:  # the baselines' reasons name no drive\n            raise",
       "tests/test_nav_realdata.py::test_the_config_sketch_of_a_real_nmea_capture_is_a_config"),
    _m("no-steering-said-as-understeer", "sar-min", "nav/navigate.py",
       "**({\"understeer\": understeer} if inputs.steering is not None else {})", "\"understeer\": understeer",
       "tests/test_nav_sarmin.py::"
       "test_navigate_says_what_it_steered_with_and_nothing_of_a_steering_the_drive_lacks"),
    _m("gated-out-count-without-total", "sar-min", "cli.py",
       "f\"{k} {v} of {v + updates.get(k, 0)} updates\"", "f\"{k} {v}\"",
       "tests/test_nav_sarmin.py::test_a_gyro_the_gate_refuses_is_warned_of"),
    _m("overwrite-refusal-worded-otherwise", "safety", "store/outputs.py",
       "raise FileExistsError(already_exists(path))",
       "raise FileExistsError(f\"{path}: already exists (use --overwrite to replace it)\")",
       "tests/test_safety.py::test_every_command_refuses_an_existing_product_in_the_same_words"),
    _m("run-directory-drive-unnamed", "safety", "cli.py",
       "give = f\": give {path / in_run}\" if (path / in_run).is_file() else \"\"", "give = \"\"",
       "tests/test_cli.py::test_a_run_directory_or_a_folder_given_as_a_drive_is_said_before_the_output"),
    _m("empty-grid-track-unsaid", "focus", "sar/focus.py",
       "where = \"\" if parse_grid(options.grid) is None else", "where = \"\" if True else",
       "tests/test_safety.py::test_an_image_no_pulse_reaches_is_refused[1]"),
    _m("focus-json-grid-box-left-out", "focus", "sar/focus.py",
       "res.drive_s, warnings, grid_enu_box(img.grid))", "res.drive_s, warnings)",
       "tests/test_sar_focus.py::test_focus_cli_writes_the_three_products"),
    _m("stamps-in-microseconds-taken-as-ns", "ingest", "ingest/series.py",
       "    return bool(as_given > 1_000_000 and 10 * as_microseconds < as_given)", "    return False",
       _QUIRKS + "test_stamps_whose_nanoseconds_hold_microseconds_are_read_as_such"),
    _m("stamps-in-microseconds-said-not-read", "ingest", "ingest/series.py",
       "        return header_ns + header_ns % 1_000_000_000 * 999", "        return header_ns",
       _QUIRKS + "test_stamps_whose_nanoseconds_hold_microseconds_are_read_as_such"),
    _m("imu-in-ned-unnamed", "inputs", "nav/inputs.py",
       "if tilt > UPSIDE_DOWN_TILT_DEG and not any(mounting) else \"\"", "if False else \"\"",
       _QUIRKS + "test_an_imu_in_ned_axes_is_named_so"),
    _m("imu-repeats-weighed-twice", "inputs", "nav/inputs.py",
       "    if len(x) < 2 or same.mean() <= MAX_REPEATED_SHARE:", "    if True:",
       _QUIRKS + "test_imu_samples_published_twice_are_counted_once"),
    _m("capture-full-scale-taken-as-int16", "ingest", "ingest/radar_block.py",
       "frame_statistics(idx, block, p.adc_bits)", "frame_statistics(idx, block)",
       "tests/test_ingest_clipping.py::test_a_12_bit_capture_clips_at_its_own_full_scale"),
    _m("rmc-positions-dropped", "ingest", "ingest/nmea.py",
       "        latlon = self._latlon(msg, 2) or (math.nan, math.nan)", "        latlon = (math.nan, math.nan)",
       _QUIRKS + "test_a_receiver_sending_rmc_alone_is_navigated_from_its_positions"),
    _m("capture-latency-unsaid", "sar-min", "nav/inputs.py",
       "    if latency_s == 0.0:\n        return streams\n", "    if True:\n        return streams\n",
       _QUIRKS + "test_a_capture_given_a_receivers_latency_is_said_to_move_its_fixes"),
    _m("dca1000-damaged-repeat-read-as-a-restart", "ingest", "ingest/dca1000_packets.py",
       "            if i == len(start) - 1 or np.any(start[i + 1:i + 1 + GOES_ON_PACKETS] > start[:i].max()):",
       "            if False:",
       "tests/test_ingest_dca1000.py::test_a_packet_repeated_with_other_data_costs_only_its_pris"),
    _m("tiles-drop-the-drives-warnings", "focus", "sar/tiles.py",
       "for r in sorted(results, key=lambda r: r.col0) for w in r.warnings))",
       "for r in sorted(results, key=lambda r: r.col0) for w in r.warnings[:0]))",
       "tests/test_integrity.py::test_a_flipped_byte_in_an_attribute_is_damage_not_another_value[drive.h5-/-created_utc]"),
    _m("track-cut-short-unsaid", "focus", "sar/focus.py",
       "    if max(early, late) <= max(MAX_UNCOVERED_S, MAX_UNCOVERED_SPACINGS * track_spacing_s(traj)):",
       "    if max(early, late) <= 10 * MAX_UNCOVERED_S:",
       "tests/test_sar_focus.py::test_a_trajectory_that_covers_part_of_the_radars_frames_is_warned_of"),
    _m("track-gap-carried-through-unsaid", "focus", "sar/focus.py",
       "    bad = (jumps > MAX_BRIDGE_JUMP_M) & (frames > 0)",
       "    bad = (jumps > 10 * MAX_BRIDGE_JUMP_M) & (frames > 0)",
       "tests/test_sar_focus.py::test_a_trajectory_with_a_gap_where_radar_frames_lie_is_warned_of"),
    _m("pixel-coarser-than-the-response-unsaid", "focus", "sar/focus.py",
       "    null = min(resolution_m, range_null_m)", "    null = max(resolution_m, range_null_m)",
       "tests/test_sar_focus.py::test_pixels_too_coarse_for_the_response_are_warned_of"),
    _m("capture-folder-in-a-folder-not-found", "inputs", "ingest/inputs.py",
       "or not_storage or nested_capture):", "or not_storage):",
       "tests/test_cli.py::test_info_of_a_folder_holding_a_capture_alone_says_what_it_holds_and_what_to_give"),
    _m("simulate-log-named-as-another-file", "inputs", "cli.py",
       "        if want and suffix != want:", "        if False:",
       "tests/test_cli.py::test_simulate_to_a_name_of_another_kind_of_file_is_refused_with_the_name_to_give"),
    _m("usage-line-arguments-in-braces", "inputs", "cli.py",
       'return [re.sub(r"^\\{([^{}]+)\\}", r"\\1", piece) for piece in pieces]', "return pieces",
       "tests/test_cli.py::test_usage_lines_show_arguments_as_named_and_a_seeds_range_as_64_bits"),
    _m("run-json-without-the-images-enu-box", "focus", "run.py",
       '"grid_enu_m": list(frep.grid_enu_m) if frep.grid_enu_m is not None else None,', "",
       "tests/test_run.py::test_run_json_gives_the_images_enu_box_as_focus_json_does"),
    _m("directory-output-named-as-a-file", "inputs", "cli.py",
       "    if output.suffix.lower() in _FILE_SUFFIXES and not output.exists():", "    if False:",
       "tests/test_cli.py::test_a_directory_output_named_as_a_file_is_refused_with_the_name_to_give"),
    _m("empty-mcap-mapped", "ingest", "ingest/mcap_source.py",
       "    if path.stat().st_size < 2 * len(MCAP_MAGIC):", "    if False:",
       "tests/test_cli.py::test_an_empty_mcap_is_named_with_what_it_is"),
    _m("debug-after-the-command-unexplained", "inputs", "cli.py",
       'if getattr(exc, "option_name", None) == "--debug":', "if False:",
       "tests/test_cli.py::test_debug_given_after_the_command_says_where_it_goes"),
    _m("asc-relative-times-read-as-absolute", "ingest", "ingest/canlog.py",
       'relative_times=suffix == ".asc" and _asc_times_relative(path))', "relative_times=False)",
       "tests/test_ingest_canlog.py::test_an_asc_whose_times_are_relative_reads_each_frame_at_its_own_time"),
    _m("can-clock-off-left-unmoved", "sar-min", "nav/navigate.py",
       "    return delayed_can(inputs, late, can), [", "    return inputs, [",
       _QUIRKS + "test_a_can_log_whose_clock_is_seconds_off_is_moved_and_named"),
    _m("can-log-clock-step-back-unsaid", "ingest", "ingest/pipeline.py",
       "                if latest - rec.t_ns > CAN_LOG_STEP_BACK_NS:", "                if False:",
       "tests/test_ingest_canlog.py::test_a_can_log_whose_clock_steps_back_while_recording_is_warned_of"),
    _m("radar-looking-through-the-car-taken", "config", "config.py",
       "    if abs(y) > track_m / 4 and y * looks < 0 and", "    if False and", CONFIG_SILENT),
    _m("radar-yaw-along-the-track-taken", "config", "config.py",
       "    if off_axis < MIN_BORESIGHT_OFF_AXIS_DEG:", "    if False:", CONFIG_SILENT),
    _m("gyro-rate-as-a-period-taken", "config", "config.py",
       'if s.kind in ("imu", "can_imu") and s.rate_hz < MIN_GYRO_RATE_HZ:', "if False:", CONFIG_SILENT),
    _m("steering-ratio-inverted-taken", "config", "config.py",
       "    if v.steering_ratio < 1.0:", "    if False:", CONFIG_SILENT),
    _m("chirp-units-unnamed", "config", "config.py",
       "if lo <= getattr(r, k) * f <= hi] if getattr(r, k) < lo else", "] if False else", CONFIG_SILENT),
    _m("tiles-skip-the-channel-check", "focus", "sar/tiles.py",
       "        warnings += [incoherent] if incoherent else []\n", "",
       "tests/test_sar_focus.py::test_a_config_that_misplaces_the_antennas_is_warned_of_in_tiles_too"),
    _m("tiles-check-the-first-tiles-brightest-pixel", "focus", "sar/tiles.py",
       "key=lambda b: (b[0], -b[1], -b[2]))", "key=lambda b: -b[2])",
       "tests/test_sar_focus.py::test_a_config_that_misplaces_the_antennas_is_warned_of_in_tiles_too"),
    _m("compare-drops-each-methods-warnings", "evaluate", "evaluate/compare.py",
       "        own[m] = [w for w in dict.fromkeys([*nav_warnings, *focus_warnings]) if w not in warnings]",
       "        own[m] = []",
       "tests/test_evaluate.py::test_a_comparison_carries_what_focus_warned_of_along_each_method"),
    _m("compare-image-keeps-no-focus-warnings", "evaluate", "evaluate/compare.py",
       '"command": command, "warnings": focus_warnings})', '"command": command, "warnings": []})',
       "tests/test_evaluate.py::test_a_comparison_carries_what_focus_warned_of_along_each_method"),
    _m("compare-checks-the-metrics-pixel", "evaluate", "evaluate/compare.py",
       "coarse = coarse_pixel_warning(image.grid.pixel_m, options.resolution_m, null)",
       "coarse = coarse_pixel_warning(metrics_image.grid.pixel_m, options.resolution_m, null)",
       "tests/test_evaluate.py::test_a_comparisons_coarse_product_pixel_is_warned_of_as_focus_warns"),
    _m("compare-skips-the-channel-check", "evaluate", "evaluate/compare.py",
       "*unfocused, *([incoherent] if incoherent else [])]))", "*unfocused]))",
       "tests/test_evaluate.py::test_a_comparison_checks_each_methods_channels_as_focus_does"),
    _m("sparse-track-gaps-judged-by-time-alone", "focus", "sar/focus.py",
       "max(MAX_BRIDGED_S, MAX_BRIDGED_SPACINGS * track_spacing_s(traj))", "MAX_BRIDGED_S",
       "tests/test_sar_focus.py::test_a_sparse_receivers_track_is_not_warned_of_as_cut_or_holed"),
    _m("can-clock-unconfirmed-unsaid", "sar-min", "nav/navigate.py",
       "        return inputs, [f\"{runs}, and the wheel speeds",
       "        return inputs, [] and [f\"{runs}, and the wheel speeds",
       _QUIRKS + "test_a_can_log_whose_clock_is_seconds_off_is_moved_and_named"),
    _m("asc-relative-damaged-line-time-dropped", "ingest", "ingest/text_lines.py",
       "                if self._relative:  # its event's time", "                if False:  # its event's time",
       "tests/test_ingest_canlog.py::test_an_asc_whose_times_are_relative_reads_each_frame_at_its_own_time"),
    _m("dca1000-damaged-repeat-judged-by-the-next-packet-alone", "ingest", "ingest/dca1000_packets.py",
       "start[i + 1:i + 1 + GOES_ON_PACKETS] > start[:i].max()", "start[i + 1:i + 2] > start[:i].max()",
       "tests/test_ingest_dca1000.py::test_a_packet_repeated_with_other_data_costs_only_its_pris"),
    _m("chirp-units-taken-outside-any-radars", "config", "config.py",
       "if lo <= getattr(r, k) * f <= hi]", "if True]", CONFIG_SILENT),
    _m("roof-mount-looking-across-refused", "config", "config.py",
       " and z < MIN_ABOVE_COG_ACROSS_THE_ROOF_M:", ":",
       "tests/test_config.py::test_a_radar_mounted_as_real_cars_carry_them_is_taken"),
    _m("range-null-of-a-blackman-taken-as-hanns", "kernel", "sar/range_compression.py",
       '"blackman": 3.0}', '"blackman": 2.0}',
       "tests/test_sar_range.py::test_a_windows_first_range_null_is_the_one_its_response_has[blackman]"),
    _m("compare-drops-each-methods-navigation-warnings", "evaluate", "evaluate/compare.py",
       '        nav_warnings = [str(w) for w in traj.info.get("warnings", [])]', "        nav_warnings = []",
       "tests/test_evaluate.py::test_a_comparison_carries_what_each_methods_navigation_warned_of"),
    _m("carrier-in-ghz-taken", "config", "config.py",
       "    if not MIN_CARRIER_HZ <= r.start_frequency_hz <= MAX_CARRIER_HZ:", "    if False:", CONFIG_SILENT),
    _m("focus-height-in-mm-taken", "config", "config.py",
       "    if abs(p.focus_height_m) > MAX_FOCUS_HEIGHT_M:", "    if False:", CONFIG_SILENT),
    _m("capture-alone-offered-radar-start-under-a-hardware-trigger", "ingest", "ingest/pipeline.py",
       "    if hardware:\n        return (", "    if False:\n        return (",
       "tests/test_ingest_dca1000.py::test_hardware_triggered_frames_take_their_triggers_times"),
    _m("geotiff-cut-as-it-closed-comes-into-place", "store", "store/image.py",
       "            if found.intact:\n                return False",
       "            if True:\n                return False",
       "tests/test_image_products.py::test_a_geotiff_cut_as_it_closed_leaves_nothing"),
    _m("navigate-writes-hdf5-under-any-name", "inputs", "cli.py",
       '        _an_hdf5_name(output, "the trajectory.h5 navigate writes")\n', "",
       "tests/test_cli.py::test_a_drive_named_as_another_kind_of_file_is_refused_with_the_name_to_give"),
    _m("slow-nmea-receivers-latency-refused-as-ms", "config", "config.py",
       "LATENCY_IN_MS_S = 1.0", "LATENCY_IN_MS_S = 0.5",
       "tests/test_config.py::test_a_slow_nmea_receivers_latency_is_taken"),
    _m("batch-retries-a-full-disk", "safety", "batch.py",
       "PermissionError, DiskFullError,", "PermissionError,",
       "tests/test_safety.py::test_a_disk_that_fills_at_any_stage_ends_each_command_with_one_line[batch]"),
    _m("drive-folder-documents-warned-as-unread", "ingest", "ingest/inputs.py",
       'name.endswith((".truth.h5", *DOCUMENT_SUFFIXES))', 'name.endswith((".truth.h5",))',
       "tests/test_ingest_drive_folder.py::test_a_folder_of_a_simulated_log_and_its_truth_is_that_log_and_finds_its_truth"),
    _m("dca-adc-data-beside-another-recordings-raw-read", "ingest", "ingest/dca1000.py",
       "        if differs := _not_its_raw_twin(folder):",
       "        if False and (differs := _not_its_raw_twin(folder)):",
       _DCA + "test_adc_data_beside_the_raw_files_of_another_recording_is_refused"),
    _m("dca-frames-past-numframes-refuse-the-capture", "ingest", "ingest/dca1000.py",
       "            self.num_frames, self.partial_bytes = p.num_frames, 0",
       "            raise CaptureError(self.warnings.pop())", _DCA + "test_malformed_sizes"),
    _m("dca-frames-past-numframes-read-as-the-recordings", "ingest", "ingest/dca1000.py",
       "            self.num_frames, self.partial_bytes = p.num_frames, 0", "            pass",
       _DCA + "test_malformed_sizes"),
    _m("dca-earlier-recordings-split-files-unsaid", "ingest", "ingest/dca1000_packets.py",
       "        if stale := _another_recordings_file(rec, offset, start, length, data_bytes, gaps_before):",
       "        if False:", _DCA + "test_an_earlier_longer_recordings_split_files_left_beside_are_said"),
    _m("dca-files-after-a-recordings-last-packet-unsaid", "ingest", "ingest/dca1000_packets.py",
       " or (gap > 0 and length[i - 1] < data_bytes):", ":",
       _DCA + "test_an_earlier_longer_recordings_split_files_left_beside_are_said"),
    _m("dca-zero-run-flagged-three-values-past-its-zeros", "ingest", "ingest/dca1000.py",
       "lo, hi = int(lo) - _zeros_beside(values, int(lo), -1), int(hi) + _zeros_beside(values, int(hi), 1)",
       "lo, hi = int(lo) - 3, int(hi) + 3",
       _DCA + "test_a_loss_that_starts_or_ends_at_a_pris_edge_costs_only_the_pris_it_touches", DCA_ZEROS),
    _m("can-log-clock-step-forward-unsaid", "ingest", "ingest/pipeline.py",
       "            if rec.t_ns - before - period > gap / 2:", "            if False:", CAN_FORWARD),
    _m("can-log-id-pausing-taken-for-a-jump", "ingest", "ingest/pipeline.py",
       "            if rec.t_ns - before - period > gap / 2:", "            if True:",
       "tests/test_ingest_canlog.py::test_a_real_can_logs_id_that_pauses_while_another_comes_on_time_is_no_jump"),
    _m("can-log-counter-gone-round-taken-as-no-frame-lost", "ingest", "ingest/pipeline.py",
       "if lost is not None and counter_step is not None and lost % 16:",
       "if lost is not None and counter_step is not None:", CAN_FORWARD),
    _m("latency-in-ms-taken", "config", "config.py",
       "        if math.isfinite(s.latency_s) and s.latency_s >= LATENCY_IN_MS_S:", "        if False:", CONFIG_SILENT),
    _m("empty-blf-in-pythons-words", "ingest", "ingest/canlog.py",
       "    if size == 0 and suffix in _BINARY:", "    if False:",
       "tests/test_cli.py::test_an_empty_binary_can_log_is_named_with_what_it_is[empty blf]"),
    _m("blf-cut-in-its-header-in-pythons-words", "ingest", "ingest/canlog.py",
       '    if suffix == ".blf" and size < _BLF_HEADER_READ:', "    if False:",
       "tests/test_cli.py::test_an_empty_binary_can_log_is_named_with_what_it_is[blf of its magic alone]"),
    _m("drive-of-any-name-written", "inputs", "cli.py",
       '    if suffix not in (".h5", ".hdf5"):', "    if False:",
       "tests/test_cli.py::test_a_drive_named_as_another_kind_of_file_is_refused_with_the_name_to_give[txt]"),
]


def _copy_package(src: Path, dst: Path) -> None:
    """dst/autosar_cli (a copy, timestamps kept: numba's cache index keys on them), configs, tests, pyproject."""
    dst.mkdir(parents=True)
    shutil.copytree(src / "autosar_cli", dst / "autosar_cli", copy_function=shutil.copy2)
    for name in ("configs", "tests", "pyproject.toml"):
        (dst / name).symlink_to(src / name if src == REPO else (src / name).resolve())


def _apply(root: Path, mutation: Mutation) -> None:
    for file, old, new in mutation.edits:
        path = root / "autosar_cli" / file
        text = path.read_text()
        if text.count(old) != 1:
            raise SystemExit(f"mutation {mutation.name}: {file} holds its snippet {text.count(old)} times, not once")
        path.write_text(text.replace(old, new))


def _pytest(root: Path, tests: list[str], timeout_s: float) -> tuple[int, float, str]:
    """Run ``tests`` in a fresh process inside ``root`` (its autosar_cli first on the path)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR")}
    env["PYTHONPATH"] = str(root)
    cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "--no-header", *tests]
    t0 = time.perf_counter()
    try:
        res = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return -1, time.perf_counter() - t0, "timeout"
    return res.returncode, time.perf_counter() - t0, res.stdout + res.stderr


def _first_failure(output: str) -> str:
    for line in output.splitlines():
        if line.startswith(("FAILED", "ERROR")):
            return line.split(" - ")[0].split("::")[-1]
    return ""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="names of the mutations to run (default: all)")
    ap.add_argument("--list", action="store_true", help="list the mutations and exit")
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per mutant")
    args = ap.parse_args(argv)
    chosen = [m for m in MUTATIONS if not args.only or m.name in args.only]
    if args.list:
        for m in chosen:
            print(f"{m.area:10s} {m.name:45s} {' '.join(t.split('::')[-1] for t in m.tests)}")
        return 0
    for m in chosen:  # every snippet is where it should be before anything runs
        for file, old, _ in m.edits:
            n = (REPO / "autosar_cli" / file).read_text().count(old)
            if n != 1:
                print(f"mutation {m.name}: autosar_cli/{file} holds its snippet {n} times, not once")
                return 2
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="autosar-mutate-") as tmp:
        base = Path(tmp) / "base"
        _copy_package(REPO, base)
        probe = subprocess.run([sys.executable, "-c", "import autosar_cli; print(autosar_cli.__file__)"], cwd=base,
                               env={**os.environ, "PYTHONPATH": str(base)}, capture_output=True, text=True)
        if not probe.stdout.startswith(str(base)):
            print(f"the copy's package is not the one imported: {probe.stdout or probe.stderr}")
            return 2
        tests = list(dict.fromkeys(t for m in chosen for t in m.tests))
        rc, secs, out = _pytest(base, tests, 1200.0)
        print(f"baseline: {len(tests)} tests {'pass' if rc == 0 else 'FAIL'} unmutated ({secs:.0f} s)")
        if rc != 0:
            print(out[-3000:])
            return 2
        rows = []
        for m in chosen:
            root = Path(tmp) / m.name
            shutil.copytree(base, root, copy_function=shutil.copy2, symlinks=True)
            try:
                _apply(root, m)
                rc, secs, out = _pytest(root, list(m.tests), args.timeout)
            finally:
                shutil.rmtree(root, ignore_errors=True)
            killed = rc != 0
            by = "timeout" if rc == -1 else _first_failure(out)
            rows.append({"name": m.name, "area": m.area, "killed": killed, "by": by, "seconds": round(secs, 1)})
            print(f"{'killed  ' if killed else 'SURVIVED'} {m.area:10s} {m.name:45s} {secs:6.1f} s  {by}", flush=True)
    survived = [r["name"] for r in rows if not r["killed"]]
    total = time.perf_counter() - t_all
    print(f"{len(rows) - len(survived)}/{len(rows)} mutations killed in {total / 60:.1f} min"
          + (f"; survived: {', '.join(survived)}" if survived else ""))
    if args.json:
        summary = {"mutations": len(rows), "killed": len(rows) - len(survived)}
        args.json.write_text(json.dumps({"total_s": round(total, 1), "summary": summary, "mutations": rows},
                                        indent=1) + "\n")
    return 1 if survived else 0


if __name__ == "__main__":
    raise SystemExit(main())
