// `stampede metrics --metadetect`: response, shear and (from a shear pair) m and c of metadetection
// catalogues (engine/analysis/metadetect_shear).
#pragma once

// argv[0] is "metrics"; called when the arguments hold --metadetect.
int run_metadetect_metrics_command(int argc, char** argv);
