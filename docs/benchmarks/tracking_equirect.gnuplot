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
colmap faces, gt H.264	0	52.24
colmap faces, gt H.264	1	51.57
colmap faces, gt H.264	2	58.21
colmap faces, gt H.264	3	52.76
colmap faces, gt H.264	4	22.82
colmap faces, gt H.264	5	14.91
colmap faces, gt H.264	6	22.73
colmap faces, gt H.264	7	9.81
colmap faces, gt H.264	8	21.83
colmap faces, gt H.264	9	12.76
colmap faces, gt H.264	10	23.36
colmap faces, gt H.264	11	38.77
colmap faces, gt H.264	12	39.16
colmap faces, gt H.264	13	34.84
colmap faces, gt H.264	14	49.10
colmap faces, gt H.264	15	47.37
colmap faces, gt H.264	16	50.00
colmap faces, gt H.264	17	41.94
colmap faces, gt H.264	18	46.13
colmap faces, gt H.264	19	28.58
colmap faces, gt H.264	20	44.80
colmap faces, gt H.264	21	11.45
colmap faces, gt H.264	22	14.23
colmap faces, gt H.264	23	52.56
colmap faces, gt H.264	24	38.21
colmap faces, gt H.264	25	25.72
colmap faces, gt H.264	26	61.73
colmap faces, gt H.264	27	16.17
colmap faces, gt H.264	28	40.29
colmap faces, gt H.264	29	39.00
colmap faces, gt H.264	30	21.20
colmap faces, gt H.264	31	59.42
colmap faces, gt H.264	32	21.90
colmap faces, gt H.264	33	31.38
colmap faces, gt H.264	34	41.70
colmap faces, gt H.264	35	20.60
colmap faces, gt H.264	36	17.65
colmap faces, gt H.264	37	14.11
colmap faces, gt H.264	38	45.53
colmap faces, gt H.264	39	80.70
odvr, stitched H.264	0	17.07
odvr, stitched H.264	1	12.16
odvr, stitched H.264	2	11.44
odvr, stitched H.264	3	10.67
odvr, stitched H.264	4	6.72
odvr, stitched H.264	5	3.32
odvr, stitched H.264	6	3.30
odvr, stitched H.264	7	7.01
odvr, stitched H.264	8	3.98
odvr, stitched H.264	9	5.37
odvr, stitched H.264	10	6.58
odvr, stitched H.264	11	9.04
odvr, stitched H.264	12	17.62
odvr, stitched H.264	13	16.75
odvr, stitched H.264	14	12.95
odvr, stitched H.264	15	9.97
odvr, stitched H.264	16	13.04
odvr, stitched H.264	17	9.22
odvr, stitched H.264	18	19.54
odvr, stitched H.264	19	14.67
odvr, stitched H.264	20	19.30
odvr, stitched H.264	21	9.43
odvr, stitched H.264	22	6.73
odvr, stitched H.264	23	20.67
odvr, stitched H.264	24	14.01
odvr, stitched H.264	25	12.14
odvr, stitched H.264	26	4.67
odvr, stitched H.264	27	19.15
odvr, stitched H.264	28	9.96
odvr, stitched H.264	29	14.44
odvr, stitched H.264	30	9.46
odvr, stitched H.264	31	11.81
odvr, stitched H.264	32	25.25
odvr, stitched H.264	33	20.44
odvr, stitched H.264	34	22.15
odvr, stitched H.264	35	23.92
odvr, stitched H.264	36	10.63
odvr, stitched H.264	37	10.18
odvr, stitched H.264	38	16.61
odvr, stitched H.264	39	16.89
odvr, stitched H.264, no height	0	17.25
odvr, stitched H.264, no height	1	12.23
odvr, stitched H.264, no height	2	11.48
odvr, stitched H.264, no height	3	10.66
odvr, stitched H.264, no height	4	6.71
odvr, stitched H.264, no height	5	3.40
odvr, stitched H.264, no height	6	3.24
odvr, stitched H.264, no height	7	6.97
odvr, stitched H.264, no height	8	3.97
odvr, stitched H.264, no height	9	5.36
odvr, stitched H.264, no height	10	6.53
odvr, stitched H.264, no height	11	9.06
odvr, stitched H.264, no height	12	17.63
odvr, stitched H.264, no height	13	16.76
odvr, stitched H.264, no height	14	12.96
odvr, stitched H.264, no height	15	10.05
odvr, stitched H.264, no height	16	12.97
odvr, stitched H.264, no height	17	9.13
odvr, stitched H.264, no height	18	19.43
odvr, stitched H.264, no height	19	14.58
odvr, stitched H.264, no height	20	19.20
odvr, stitched H.264, no height	21	9.41
odvr, stitched H.264, no height	22	6.91
odvr, stitched H.264, no height	23	20.65
odvr, stitched H.264, no height	24	14.07
odvr, stitched H.264, no height	25	12.13
odvr, stitched H.264, no height	26	4.73
odvr, stitched H.264, no height	27	18.95
odvr, stitched H.264, no height	28	10.15
odvr, stitched H.264, no height	29	14.71
odvr, stitched H.264, no height	30	9.66
odvr, stitched H.264, no height	31	11.67
odvr, stitched H.264, no height	32	25.04
odvr, stitched H.264, no height	33	20.33
odvr, stitched H.264, no height	34	22.42
odvr, stitched H.264, no height	35	24.04
odvr, stitched H.264, no height	36	10.78
odvr, stitched H.264, no height	37	10.06
odvr, stitched H.264, no height	38	16.59
odvr, stitched H.264, no height	39	16.68
colmap faces, stitched H.264	0	147.33
colmap faces, stitched H.264	1	107.86
colmap faces, stitched H.264	2	131.54
colmap faces, stitched H.264	3	75.58
colmap faces, stitched H.264	4	90.45
colmap faces, stitched H.264	5	67.96
colmap faces, stitched H.264	6	53.75
colmap faces, stitched H.264	7	43.25
colmap faces, stitched H.264	8	32.75
colmap faces, stitched H.264	9	20.60
colmap faces, stitched H.264	10	35.74
colmap faces, stitched H.264	11	53.85
colmap faces, stitched H.264	12	70.98
colmap faces, stitched H.264	13	77.13
colmap faces, stitched H.264	14	84.59
colmap faces, stitched H.264	15	93.49
colmap faces, stitched H.264	16	113.05
colmap faces, stitched H.264	17	109.52
colmap faces, stitched H.264	18	112.91
colmap faces, stitched H.264	19	105.32
colmap faces, stitched H.264	20	85.59
colmap faces, stitched H.264	21	73.75
colmap faces, stitched H.264	22	95.75
colmap faces, stitched H.264	23	71.46
colmap faces, stitched H.264	24	54.23
colmap faces, stitched H.264	25	42.65
colmap faces, stitched H.264	26	47.75
colmap faces, stitched H.264	27	20.03
colmap faces, stitched H.264	28	19.90
colmap faces, stitched H.264	29	23.33
colmap faces, stitched H.264	30	29.87
colmap faces, stitched H.264	31	21.91
colmap faces, stitched H.264	32	19.09
colmap faces, stitched H.264	33	33.26
colmap faces, stitched H.264	34	47.33
colmap faces, stitched H.264	35	65.14
colmap faces, stitched H.264	36	90.94
colmap faces, stitched H.264	37	91.08
colmap faces, stitched H.264	38	98.89
colmap faces, stitched H.264	39	89.21
odvr, stitched H.264 tracked at 2048	0	7.43
odvr, stitched H.264 tracked at 2048	1	6.69
odvr, stitched H.264 tracked at 2048	2	5.66
odvr, stitched H.264 tracked at 2048	3	4.50
odvr, stitched H.264 tracked at 2048	4	6.63
odvr, stitched H.264 tracked at 2048	5	3.29
odvr, stitched H.264 tracked at 2048	6	2.95
odvr, stitched H.264 tracked at 2048	7	5.18
odvr, stitched H.264 tracked at 2048	8	2.88
odvr, stitched H.264 tracked at 2048	9	1.21
odvr, stitched H.264 tracked at 2048	10	10.30
odvr, stitched H.264 tracked at 2048	11	10.65
odvr, stitched H.264 tracked at 2048	12	4.67
odvr, stitched H.264 tracked at 2048	13	3.19
odvr, stitched H.264 tracked at 2048	14	4.34
odvr, stitched H.264 tracked at 2048	15	5.11
odvr, stitched H.264 tracked at 2048	16	10.14
odvr, stitched H.264 tracked at 2048	17	9.55
odvr, stitched H.264 tracked at 2048	18	4.95
odvr, stitched H.264 tracked at 2048	19	4.56
odvr, stitched H.264 tracked at 2048	20	7.05
odvr, stitched H.264 tracked at 2048	21	11.51
odvr, stitched H.264 tracked at 2048	22	6.81
odvr, stitched H.264 tracked at 2048	23	11.86
odvr, stitched H.264 tracked at 2048	24	11.99
odvr, stitched H.264 tracked at 2048	25	9.68
odvr, stitched H.264 tracked at 2048	26	10.16
odvr, stitched H.264 tracked at 2048	27	14.29
odvr, stitched H.264 tracked at 2048	28	17.75
odvr, stitched H.264 tracked at 2048	29	19.88
odvr, stitched H.264 tracked at 2048	30	19.08
odvr, stitched H.264 tracked at 2048	31	7.97
odvr, stitched H.264 tracked at 2048	32	4.11
odvr, stitched H.264 tracked at 2048	33	4.67
odvr, stitched H.264 tracked at 2048	34	3.39
odvr, stitched H.264 tracked at 2048	35	5.35
odvr, stitched H.264 tracked at 2048	36	16.22
odvr, stitched H.264 tracked at 2048	37	22.61
odvr, stitched H.264 tracked at 2048	38	20.99
odvr, stitched H.264 tracked at 2048	39	29.24
odvr rig	0	8.48
odvr rig	1	7.56
odvr rig	2	6.12
odvr rig	3	5.16
odvr rig	4	4.10
odvr rig	5	3.59
odvr rig	6	2.39
odvr rig	7	4.40
odvr rig	8	2.99
odvr rig	9	4.05
odvr rig	10	3.52
odvr rig	11	5.66
odvr rig	12	7.09
odvr rig	13	5.38
odvr rig	14	5.22
odvr rig	15	3.94
odvr rig	16	4.75
odvr rig	17	3.69
odvr rig	18	3.06
odvr rig	19	3.78
odvr rig	20	2.60
odvr rig	21	2.34
odvr rig	22	3.52
odvr rig	23	4.76
odvr rig	24	2.68
odvr rig	25	2.30
odvr rig	26	2.62
odvr rig	27	3.25
odvr rig	28	3.41
odvr rig	29	3.32
odvr rig	30	3.99
odvr rig	31	1.74
odvr rig	32	3.06
odvr rig	33	3.69
odvr rig	34	1.24
odvr rig	35	6.69
odvr rig	36	6.30
odvr rig	37	6.41
odvr rig	38	4.89
odvr rig	39	5.14
EOD
set datafile separator '\t'
set multiplot layout 2,1
set key outside right
set grid
set size ratio -1
set title 'trajectory seen from above (ground-truth world, estimates similarity-aligned)'
set xlabel 'x (m)'
set ylabel 'y (m)'
plot 'tracking_equirect_paths.tsv' using (strcol(1) eq 'ground truth' ? $3 : 1/0):4 with lines lw 5 lc rgb '#aaaaaa' title 'ground truth', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264 tracked at 2048' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 7 title 'odvr, stitched H.264 tracked at 2048', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr rig' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 8 title 'odvr rig'
set size noratio
set title 'position error after the alignment'
set xlabel 'frame'
set ylabel 'mm'
set logscale y
plot $errors using (strcol(1) eq 'odvr, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', $errors using (strcol(1) eq 'odvr, gt H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', $errors using (strcol(1) eq 'colmap faces, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', $errors using (strcol(1) eq 'odvr, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', $errors using (strcol(1) eq 'odvr, stitched H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', $errors using (strcol(1) eq 'colmap faces, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', $errors using (strcol(1) eq 'odvr, stitched H.264 tracked at 2048' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 7 title 'odvr, stitched H.264 tracked at 2048', $errors using (strcol(1) eq 'odvr rig' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 8 title 'odvr rig'
unset multiplot
