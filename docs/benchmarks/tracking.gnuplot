set terminal pngcairo size 1000,900 noenhanced
set output 'tracking.png'
$errors << EOD
odvr	0	9.01
odvr	1	8.41
odvr	2	6.39
odvr	3	5.77
odvr	4	5.70
odvr	5	3.10
odvr	6	0.94
odvr	7	2.53
odvr	8	1.47
odvr	9	4.55
odvr	10	2.58
odvr	11	3.21
odvr	12	13.45
odvr	13	6.34
odvr	14	4.17
odvr	15	6.40
odvr	16	6.28
odvr	17	4.20
odvr	18	3.90
odvr	19	5.96
odvr	20	7.72
odvr	21	7.20
odvr	22	5.91
odvr	23	6.49
odvr	24	4.96
odvr	25	3.29
odvr	26	3.92
odvr	27	3.03
odvr	28	2.42
odvr	29	4.14
odvr	30	3.71
odvr	31	3.62
odvr	32	6.12
odvr	33	3.41
odvr	34	2.27
odvr	35	2.34
odvr	36	4.18
odvr	37	4.32
odvr	38	4.59
odvr	39	7.35
colmap	0	35.25
colmap	1	24.96
colmap	2	18.25
colmap	3	9.23
colmap	4	8.68
colmap	5	7.10
colmap	6	3.31
colmap	7	4.09
colmap	8	8.61
colmap	9	8.57
colmap	10	11.04
colmap	11	13.53
colmap	12	16.24
colmap	13	14.28
colmap	14	12.89
colmap	15	10.34
colmap	16	10.15
colmap	17	10.93
colmap	18	11.37
colmap	19	10.63
colmap	20	13.17
colmap	21	9.30
colmap	22	9.30
colmap	23	7.36
colmap	24	9.92
colmap	25	8.89
colmap	26	6.91
colmap	27	10.35
colmap	28	10.40
colmap	29	10.06
colmap	30	9.81
colmap	31	4.22
colmap	32	5.44
colmap	33	5.32
colmap	34	7.41
colmap	35	6.71
colmap	36	8.90
colmap	37	10.58
colmap	38	11.20
colmap	39	13.09
EOD
set datafile separator '\t'
set multiplot layout 2,1
set key outside right
set grid
set size ratio -1
set title 'rig trajectory seen from above (ground-truth world, estimates similarity-aligned)'
set xlabel 'x (m)'
set ylabel 'y (m)'
plot 'tracking_paths.tsv' using (strcol(1) eq 'ground truth' ? $3 : 1/0):4 with lines lw 5 lc rgb '#aaaaaa' title 'ground truth', 'tracking_paths.tsv' using (strcol(1) eq 'odvr' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 1 title 'odvr', 'tracking_paths.tsv' using (strcol(1) eq 'colmap' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 2 title 'colmap'
set size noratio
set title 'position error after the alignment'
set xlabel 'frame'
set ylabel 'mm'
set logscale y
plot $errors using (strcol(1) eq 'odvr' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 1 title 'odvr', $errors using (strcol(1) eq 'colmap' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 2 title 'colmap'
unset multiplot
