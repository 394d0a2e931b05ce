set terminal pngcairo size 900,560 noenhanced
set output 'render_set.png'
set datafile separator '\t'
set key bottom right
set grid
set yrange [0:1]
set logscale x
set title 'car pixels: share of the set at or under an error'
set xlabel 'mean relative error'
set ylabel 'share of the images'
plot 'render_set.tsv' using 5:(1) smooth cnormal lw 2 title 'whole car', '' using 8:(1) smooth cnormal lw 2 title 'upper half', '' using 10:(1) smooth cnormal lw 2 title 'lower quarter'
