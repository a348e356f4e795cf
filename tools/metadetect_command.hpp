// `stampede metadetect`: metadetection of image files (app/metadetect_run).
#pragma once

int run_metadetect_command(int argc, char** argv);
