set terminal pngcairo size 1000,600 noenhanced
set output 'render.png'
set datafile separator '\t'
set logscale xy
set key outside right
set grid
set title 'car pixels: mean relative error against Cycles vs shade time'
set xlabel 'shade ms'
set ylabel 'mean relative error'
plot 'render.tsv' using (strcol(2) eq 'sg' && $16 > 0 ? $17 : 1/0):10 with points pt 7 title 'SG triple product', 'render.tsv' using (strcol(2) eq 'mc' && $16 > 0 ? $17 : 1/0):10 with points pt 5 title 'Monte-Carlo'
