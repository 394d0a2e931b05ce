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
colmap faces, gt H.264	0	58.06
colmap faces, gt H.264	1	58.07
colmap faces, gt H.264	2	63.37
colmap faces, gt H.264	3	59.62
colmap faces, gt H.264	4	33.87
colmap faces, gt H.264	5	23.25
colmap faces, gt H.264	6	17.54
colmap faces, gt H.264	7	6.21
colmap faces, gt H.264	8	20.67
colmap faces, gt H.264	9	10.68
colmap faces, gt H.264	10	22.07
colmap faces, gt H.264	11	25.87
colmap faces, gt H.264	12	35.32
colmap faces, gt H.264	13	24.72
colmap faces, gt H.264	14	38.80
colmap faces, gt H.264	15	51.02
colmap faces, gt H.264	16	51.82
colmap faces, gt H.264	17	43.42
colmap faces, gt H.264	18	40.56
colmap faces, gt H.264	19	38.65
colmap faces, gt H.264	20	42.58
colmap faces, gt H.264	21	27.07
colmap faces, gt H.264	22	40.74
colmap faces, gt H.264	23	51.75
colmap faces, gt H.264	24	44.35
colmap faces, gt H.264	25	45.34
colmap faces, gt H.264	26	28.31
colmap faces, gt H.264	27	79.62
colmap faces, gt H.264	28	148.85
colmap faces, gt H.264	29	47.29
colmap faces, gt H.264	30	48.10
colmap faces, gt H.264	31	49.71
colmap faces, gt H.264	32	33.74
colmap faces, gt H.264	33	42.75
colmap faces, gt H.264	34	56.40
colmap faces, gt H.264	35	44.02
colmap faces, gt H.264	36	50.80
colmap faces, gt H.264	37	51.00
colmap faces, gt H.264	38	51.07
colmap faces, gt H.264	39	48.78
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
colmap faces, stitched H.264	0	46.16
colmap faces, stitched H.264	1	97.01
colmap faces, stitched H.264	2	86.21
colmap faces, stitched H.264	3	65.31
colmap faces, stitched H.264	4	46.77
colmap faces, stitched H.264	5	47.02
colmap faces, stitched H.264	6	43.94
colmap faces, stitched H.264	7	32.41
colmap faces, stitched H.264	8	32.36
colmap faces, stitched H.264	9	21.71
colmap faces, stitched H.264	10	18.19
colmap faces, stitched H.264	11	32.78
colmap faces, stitched H.264	12	39.36
colmap faces, stitched H.264	13	51.05
colmap faces, stitched H.264	14	68.32
colmap faces, stitched H.264	15	55.08
colmap faces, stitched H.264	16	78.94
colmap faces, stitched H.264	17	76.87
colmap faces, stitched H.264	18	90.95
colmap faces, stitched H.264	19	81.75
colmap faces, stitched H.264	20	85.06
colmap faces, stitched H.264	21	54.25
colmap faces, stitched H.264	22	49.40
colmap faces, stitched H.264	23	56.67
colmap faces, stitched H.264	24	38.94
colmap faces, stitched H.264	25	30.40
colmap faces, stitched H.264	26	22.37
colmap faces, stitched H.264	27	13.98
colmap faces, stitched H.264	28	12.89
colmap faces, stitched H.264	29	7.49
colmap faces, stitched H.264	30	6.35
colmap faces, stitched H.264	31	4.26
colmap faces, stitched H.264	32	25.19
colmap faces, stitched H.264	33	16.23
colmap faces, stitched H.264	34	38.56
colmap faces, stitched H.264	35	55.70
colmap faces, stitched H.264	36	58.88
colmap faces, stitched H.264	37	55.65
colmap faces, stitched H.264	38	76.62
colmap faces, stitched H.264	39	79.83
odvr rig	0	12.27
odvr rig	1	11.22
odvr rig	2	8.63
odvr rig	3	6.72
odvr rig	4	3.91
odvr rig	5	3.92
odvr rig	6	1.53
odvr rig	7	2.27
odvr rig	8	2.22
odvr rig	9	2.04
odvr rig	10	4.15
odvr rig	11	6.00
odvr rig	12	5.08
odvr rig	13	7.80
odvr rig	14	2.84
odvr rig	15	3.71
odvr rig	16	4.90
odvr rig	17	4.15
odvr rig	18	4.49
odvr rig	19	4.24
odvr rig	20	6.56
odvr rig	21	9.66
odvr rig	22	6.10
odvr rig	23	7.72
odvr rig	24	5.33
odvr rig	25	7.14
odvr rig	26	5.18
odvr rig	27	4.03
odvr rig	28	4.59
odvr rig	29	0.51
odvr rig	30	3.86
odvr rig	31	4.92
odvr rig	32	4.38
odvr rig	33	5.15
odvr rig	34	3.21
odvr rig	35	6.56
odvr rig	36	3.44
odvr rig	37	4.36
odvr rig	38	7.83
odvr rig	39	8.58
EOD
set datafile separator '\t'
set multiplot layout 2,1
set key outside right
set grid
set size ratio -1
set title 'trajectory seen from above (ground-truth world, estimates similarity-aligned)'
set xlabel 'x (m)'
set ylabel 'y (m)'
plot 'tracking_equirect_paths.tsv' using (strcol(1) eq 'ground truth' ? $3 : 1/0):4 with lines lw 5 lc rgb '#aaaaaa' title 'ground truth', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr rig' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 7 title 'odvr rig'
set size noratio
set title 'position error after the alignment'
set xlabel 'frame'
set ylabel 'mm'
set logscale y
plot $errors using (strcol(1) eq 'odvr, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', $errors using (strcol(1) eq 'odvr, gt H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', $errors using (strcol(1) eq 'colmap faces, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', $errors using (strcol(1) eq 'odvr, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', $errors using (strcol(1) eq 'odvr, stitched H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', $errors using (strcol(1) eq 'colmap faces, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', $errors using (strcol(1) eq 'odvr rig' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 7 title 'odvr rig'
unset multiplot
