set terminal pngcairo size 1000,900 noenhanced
set output 'tracking_equirect.png'
$errors << EOD
odvr, gt H.264	0	22.47
odvr, gt H.264	1	22.50
odvr, gt H.264	2	21.59
odvr, gt H.264	3	21.93
odvr, gt H.264	4	16.98
odvr, gt H.264	5	20.42
odvr, gt H.264	6	14.72
odvr, gt H.264	7	6.36
odvr, gt H.264	8	4.34
odvr, gt H.264	9	8.29
odvr, gt H.264	10	13.52
odvr, gt H.264	11	12.39
odvr, gt H.264	12	17.68
odvr, gt H.264	13	19.08
odvr, gt H.264	14	16.05
odvr, gt H.264	15	20.89
odvr, gt H.264	16	21.61
odvr, gt H.264	17	27.27
odvr, gt H.264	18	16.97
odvr, gt H.264	19	11.05
odvr, gt H.264	20	9.74
odvr, gt H.264	21	14.48
odvr, gt H.264	22	14.45
odvr, gt H.264	23	13.44
odvr, gt H.264	24	16.05
odvr, gt H.264	25	19.11
odvr, gt H.264	26	17.27
odvr, gt H.264	27	16.76
odvr, gt H.264	28	19.18
odvr, gt H.264	29	10.01
odvr, gt H.264	30	11.00
odvr, gt H.264	31	17.14
odvr, gt H.264	32	10.41
odvr, gt H.264	33	14.42
odvr, gt H.264	34	14.63
odvr, gt H.264	35	15.59
odvr, gt H.264	36	14.46
odvr, gt H.264	37	14.15
odvr, gt H.264	38	18.34
odvr, gt H.264	39	24.60
odvr, gt H.264, no height	0	22.47
odvr, gt H.264, no height	1	22.50
odvr, gt H.264, no height	2	21.59
odvr, gt H.264, no height	3	21.93
odvr, gt H.264, no height	4	16.98
odvr, gt H.264, no height	5	20.42
odvr, gt H.264, no height	6	14.72
odvr, gt H.264, no height	7	6.36
odvr, gt H.264, no height	8	4.34
odvr, gt H.264, no height	9	8.29
odvr, gt H.264, no height	10	13.52
odvr, gt H.264, no height	11	12.39
odvr, gt H.264, no height	12	17.68
odvr, gt H.264, no height	13	19.08
odvr, gt H.264, no height	14	16.05
odvr, gt H.264, no height	15	20.89
odvr, gt H.264, no height	16	21.61
odvr, gt H.264, no height	17	27.27
odvr, gt H.264, no height	18	16.97
odvr, gt H.264, no height	19	11.05
odvr, gt H.264, no height	20	9.74
odvr, gt H.264, no height	21	14.48
odvr, gt H.264, no height	22	14.45
odvr, gt H.264, no height	23	13.44
odvr, gt H.264, no height	24	16.05
odvr, gt H.264, no height	25	19.11
odvr, gt H.264, no height	26	17.27
odvr, gt H.264, no height	27	16.76
odvr, gt H.264, no height	28	19.18
odvr, gt H.264, no height	29	10.01
odvr, gt H.264, no height	30	11.00
odvr, gt H.264, no height	31	17.14
odvr, gt H.264, no height	32	10.41
odvr, gt H.264, no height	33	14.42
odvr, gt H.264, no height	34	14.63
odvr, gt H.264, no height	35	15.59
odvr, gt H.264, no height	36	14.46
odvr, gt H.264, no height	37	14.15
odvr, gt H.264, no height	38	18.34
odvr, gt H.264, no height	39	24.60
colmap faces, gt H.264	0	48.51
colmap faces, gt H.264	1	45.82
colmap faces, gt H.264	2	49.74
colmap faces, gt H.264	3	46.82
colmap faces, gt H.264	4	27.11
colmap faces, gt H.264	5	17.54
colmap faces, gt H.264	6	17.26
colmap faces, gt H.264	7	12.19
colmap faces, gt H.264	8	29.43
colmap faces, gt H.264	9	7.35
colmap faces, gt H.264	10	28.73
colmap faces, gt H.264	11	23.76
colmap faces, gt H.264	12	31.04
colmap faces, gt H.264	13	21.20
colmap faces, gt H.264	14	26.64
colmap faces, gt H.264	15	51.31
colmap faces, gt H.264	16	45.70
colmap faces, gt H.264	17	40.21
colmap faces, gt H.264	18	31.93
colmap faces, gt H.264	19	25.33
colmap faces, gt H.264	20	21.93
colmap faces, gt H.264	21	20.67
colmap faces, gt H.264	22	32.33
colmap faces, gt H.264	23	59.34
colmap faces, gt H.264	24	46.90
colmap faces, gt H.264	25	39.06
colmap faces, gt H.264	26	14.76
colmap faces, gt H.264	27	71.78
colmap faces, gt H.264	28	115.60
colmap faces, gt H.264	29	32.76
colmap faces, gt H.264	30	34.61
colmap faces, gt H.264	31	49.02
colmap faces, gt H.264	32	20.35
colmap faces, gt H.264	33	33.38
colmap faces, gt H.264	34	45.72
colmap faces, gt H.264	35	17.69
colmap faces, gt H.264	36	24.78
colmap faces, gt H.264	37	36.53
colmap faces, gt H.264	38	49.50
colmap faces, gt H.264	39	74.87
odvr, stitched H.264	0	35.33
odvr, stitched H.264	1	31.75
odvr, stitched H.264	2	34.96
odvr, stitched H.264	3	28.57
odvr, stitched H.264	4	27.98
odvr, stitched H.264	5	24.25
odvr, stitched H.264	6	19.82
odvr, stitched H.264	7	21.58
odvr, stitched H.264	8	12.40
odvr, stitched H.264	9	11.51
odvr, stitched H.264	10	5.81
odvr, stitched H.264	11	7.04
odvr, stitched H.264	12	8.96
odvr, stitched H.264	13	13.43
odvr, stitched H.264	14	12.48
odvr, stitched H.264	15	23.29
odvr, stitched H.264	16	42.44
odvr, stitched H.264	17	57.86
odvr, stitched H.264	18	47.29
odvr, stitched H.264	19	53.08
odvr, stitched H.264	20	48.00
odvr, stitched H.264	21	36.45
odvr, stitched H.264	22	39.14
odvr, stitched H.264	23	25.89
odvr, stitched H.264	24	22.90
odvr, stitched H.264	25	16.19
odvr, stitched H.264	26	16.69
odvr, stitched H.264	27	22.48
odvr, stitched H.264	28	16.53
odvr, stitched H.264	29	17.70
odvr, stitched H.264	30	17.56
odvr, stitched H.264	31	18.42
odvr, stitched H.264	32	14.11
odvr, stitched H.264	33	12.77
odvr, stitched H.264	34	13.85
odvr, stitched H.264	35	28.84
odvr, stitched H.264	36	32.31
odvr, stitched H.264	37	56.51
odvr, stitched H.264	38	54.82
odvr, stitched H.264	39	68.99
odvr, stitched H.264, no height	0	29.92
odvr, stitched H.264, no height	1	27.37
odvr, stitched H.264, no height	2	31.15
odvr, stitched H.264, no height	3	25.23
odvr, stitched H.264, no height	4	24.89
odvr, stitched H.264, no height	5	21.11
odvr, stitched H.264, no height	6	17.27
odvr, stitched H.264, no height	7	18.85
odvr, stitched H.264, no height	8	10.74
odvr, stitched H.264, no height	9	10.30
odvr, stitched H.264, no height	10	6.21
odvr, stitched H.264, no height	11	6.63
odvr, stitched H.264, no height	12	8.01
odvr, stitched H.264, no height	13	12.99
odvr, stitched H.264, no height	14	12.36
odvr, stitched H.264, no height	15	24.01
odvr, stitched H.264, no height	16	40.81
odvr, stitched H.264, no height	17	55.67
odvr, stitched H.264, no height	18	45.79
odvr, stitched H.264, no height	19	51.16
odvr, stitched H.264, no height	20	46.56
odvr, stitched H.264, no height	21	36.33
odvr, stitched H.264, no height	22	36.58
odvr, stitched H.264, no height	23	24.50
odvr, stitched H.264, no height	24	13.09
odvr, stitched H.264, no height	25	3.86
odvr, stitched H.264, no height	26	7.43
odvr, stitched H.264, no height	27	17.65
odvr, stitched H.264, no height	28	16.45
odvr, stitched H.264, no height	29	20.75
odvr, stitched H.264, no height	30	23.02
odvr, stitched H.264, no height	31	20.65
odvr, stitched H.264, no height	32	11.26
odvr, stitched H.264, no height	33	15.04
odvr, stitched H.264, no height	34	19.98
odvr, stitched H.264, no height	35	27.10
odvr, stitched H.264, no height	36	41.90
odvr, stitched H.264, no height	37	35.21
odvr, stitched H.264, no height	38	32.47
odvr, stitched H.264, no height	39	48.64
colmap faces, stitched H.264	0	59.73
colmap faces, stitched H.264	1	107.43
colmap faces, stitched H.264	2	91.36
colmap faces, stitched H.264	3	68.74
colmap faces, stitched H.264	4	47.79
colmap faces, stitched H.264	5	43.63
colmap faces, stitched H.264	6	43.41
colmap faces, stitched H.264	7	25.71
colmap faces, stitched H.264	8	27.71
colmap faces, stitched H.264	9	11.55
colmap faces, stitched H.264	10	18.46
colmap faces, stitched H.264	11	36.41
colmap faces, stitched H.264	12	41.43
colmap faces, stitched H.264	13	53.62
colmap faces, stitched H.264	14	71.72
colmap faces, stitched H.264	15	55.77
colmap faces, stitched H.264	16	80.99
colmap faces, stitched H.264	17	77.33
colmap faces, stitched H.264	18	91.03
colmap faces, stitched H.264	19	79.66
colmap faces, stitched H.264	20	87.76
colmap faces, stitched H.264	21	57.21
colmap faces, stitched H.264	22	47.97
colmap faces, stitched H.264	23	57.61
colmap faces, stitched H.264	24	40.49
colmap faces, stitched H.264	25	28.05
colmap faces, stitched H.264	26	20.36
colmap faces, stitched H.264	27	18.05
colmap faces, stitched H.264	28	7.65
colmap faces, stitched H.264	29	13.76
colmap faces, stitched H.264	30	7.77
colmap faces, stitched H.264	31	9.21
colmap faces, stitched H.264	32	24.16
colmap faces, stitched H.264	33	16.08
colmap faces, stitched H.264	34	40.64
colmap faces, stitched H.264	35	59.49
colmap faces, stitched H.264	36	56.18
colmap faces, stitched H.264	37	64.52
colmap faces, stitched H.264	38	83.60
colmap faces, stitched H.264	39	83.03
odvr, stitched H.264 at 2048	0	35.75
odvr, stitched H.264 at 2048	1	31.77
odvr, stitched H.264 at 2048	2	25.22
odvr, stitched H.264 at 2048	3	20.62
odvr, stitched H.264 at 2048	4	18.68
odvr, stitched H.264 at 2048	5	20.49
odvr, stitched H.264 at 2048	6	14.82
odvr, stitched H.264 at 2048	7	8.98
odvr, stitched H.264 at 2048	8	3.11
odvr, stitched H.264 at 2048	9	4.94
odvr, stitched H.264 at 2048	10	14.90
odvr, stitched H.264 at 2048	11	18.02
odvr, stitched H.264 at 2048	12	4.33
odvr, stitched H.264 at 2048	13	22.80
odvr, stitched H.264 at 2048	14	20.91
odvr, stitched H.264 at 2048	15	19.92
odvr, stitched H.264 at 2048	16	24.51
odvr, stitched H.264 at 2048	17	30.83
odvr, stitched H.264 at 2048	18	32.48
odvr, stitched H.264 at 2048	19	28.28
odvr, stitched H.264 at 2048	20	23.33
odvr, stitched H.264 at 2048	21	16.89
odvr, stitched H.264 at 2048	22	11.35
odvr, stitched H.264 at 2048	23	8.24
odvr, stitched H.264 at 2048	24	13.70
odvr, stitched H.264 at 2048	25	9.45
odvr, stitched H.264 at 2048	26	14.06
odvr, stitched H.264 at 2048	27	6.73
odvr, stitched H.264 at 2048	28	6.63
odvr, stitched H.264 at 2048	29	5.00
odvr, stitched H.264 at 2048	30	6.28
odvr, stitched H.264 at 2048	31	7.83
odvr, stitched H.264 at 2048	32	2.27
odvr, stitched H.264 at 2048	33	4.96
odvr, stitched H.264 at 2048	34	22.01
odvr, stitched H.264 at 2048	35	27.62
odvr, stitched H.264 at 2048	36	37.09
odvr, stitched H.264 at 2048	37	13.98
odvr, stitched H.264 at 2048	38	43.10
odvr, stitched H.264 at 2048	39	12.92
odvr rig	0	8.80
odvr rig	1	7.78
odvr rig	2	6.51
odvr rig	3	5.67
odvr rig	4	4.58
odvr rig	5	3.23
odvr rig	6	1.77
odvr rig	7	3.17
odvr rig	8	2.32
odvr rig	9	3.08
odvr rig	10	3.50
odvr rig	11	6.32
odvr rig	12	6.47
odvr rig	13	3.43
odvr rig	14	4.76
odvr rig	15	4.41
odvr rig	16	5.68
odvr rig	17	4.74
odvr rig	18	4.00
odvr rig	19	4.74
odvr rig	20	2.94
odvr rig	21	2.44
odvr rig	22	6.86
odvr rig	23	2.87
odvr rig	24	2.78
odvr rig	25	1.88
odvr rig	26	1.02
odvr rig	27	1.54
odvr rig	28	5.17
odvr rig	29	4.12
odvr rig	30	3.67
odvr rig	31	2.36
odvr rig	32	3.94
odvr rig	33	1.47
odvr rig	34	2.98
odvr rig	35	3.79
odvr rig	36	5.11
odvr rig	37	5.63
odvr rig	38	2.56
odvr rig	39	5.95
EOD
set datafile separator '\t'
set multiplot layout 2,1
set key outside right
set grid
set size ratio -1
set title 'trajectory seen from above (ground-truth world, estimates similarity-aligned)'
set xlabel 'x (m)'
set ylabel 'y (m)'
plot 'tracking_equirect_paths.tsv' using (strcol(1) eq 'ground truth' ? $3 : 1/0):4 with lines lw 5 lc rgb '#aaaaaa' title 'ground truth', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264 at 2048' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 7 title 'odvr, stitched H.264 at 2048', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr rig' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 8 title 'odvr rig'
set size noratio
set title 'position error after the alignment'
set xlabel 'frame'
set ylabel 'mm'
set logscale y
plot $errors using (strcol(1) eq 'odvr, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', $errors using (strcol(1) eq 'odvr, gt H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', $errors using (strcol(1) eq 'colmap faces, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', $errors using (strcol(1) eq 'odvr, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', $errors using (strcol(1) eq 'odvr, stitched H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', $errors using (strcol(1) eq 'colmap faces, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', $errors using (strcol(1) eq 'odvr, stitched H.264 at 2048' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 7 title 'odvr, stitched H.264 at 2048', $errors using (strcol(1) eq 'odvr rig' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 8 title 'odvr rig'
unset multiplot
